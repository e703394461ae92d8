// The planar INS: one mechanisation step by hand and its Jacobian against numbers, the
// stationarity detectors on hand-made samples, and UWB/INS fusion on the simulated AGV room
// (the improved Sage-Husa paper's set-up: 3 anchors, IMU 150 Hz, no UWB from 15 to 17 s).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "simulated_scenario.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/ins.hpp"

using namespace uwbloc;

namespace {

loc::ImuSample sample(double t, double ax, double ay, double gz) {
  loc::ImuSample s;
  s.t = t;
  s.accel = Eigen::Vector2d(ax, ay);
  s.gyro_z = gz;
  return s;
}

}  // namespace

// p = (1, 2), v = (1, 0), heading 90°, no biases; f = (1, 0) in the body frame, ω = 0.2 rad/s,
// dt = 0.5 s. The world acceleration is R(90°) f = (0, 1): p' = p + v dt + a dt²/2 =
// (1.5, 2.125), v' = (1, 0.5), heading 90° + 0.1 rad. With biases (f and ω read 0.5 and 0.1
// high) the same step follows from the corrected rates.
TEST(Ins, OneMechanisationStepByHand) {
  loc::InsState s;
  s.p = Eigen::Vector2d(1, 2);
  s.v = Eigen::Vector2d(1, 0);
  s.yaw = M_PI / 2;
  auto out = loc::mechanise(s, sample(0.5, 1.0, 0.0, 0.2), 0.5);
  EXPECT_NEAR(out.p.x(), 1.5, 1e-12);
  EXPECT_NEAR(out.p.y(), 2.125, 1e-12);
  EXPECT_NEAR(out.v.x(), 1.0, 1e-12);
  EXPECT_NEAR(out.v.y(), 0.5, 1e-12);
  EXPECT_NEAR(out.yaw, M_PI / 2 + 0.1, 1e-12);
  s.accel_bias = Eigen::Vector2d(0.5, 0.0);
  s.gyro_bias = 0.1;
  out = loc::mechanise(s, sample(0.5, 1.5, 0.0, 0.3), 0.5);
  EXPECT_NEAR(out.p.y(), 2.125, 1e-12);
  EXPECT_NEAR(out.yaw, M_PI / 2 + 0.1, 1e-12);
}

TEST(Ins, JacobianAgainstNumbers) {
  loc::InsState s;
  s.p = Eigen::Vector2d(0.3, -1.0);
  s.v = Eigen::Vector2d(0.4, 0.2);
  s.yaw = 0.7;
  s.gyro_bias = 0.01;
  s.accel_bias = Eigen::Vector2d(0.05, -0.02);
  const auto imu = sample(0.0, 0.8, -0.3, 0.25);
  const double dt = 0.02;
  Eigen::Matrix<double, 8, 8> f;
  loc::mechanise(s, imu, dt, &f);
  auto vec = [](const loc::InsState& x) {
    Eigen::Matrix<double, 8, 1> v;
    v << x.p, x.v, x.yaw, x.gyro_bias, x.accel_bias;
    return v;
  };
  auto state = [](const Eigen::Matrix<double, 8, 1>& v) {
    loc::InsState x;
    x.p = v.segment<2>(0);
    x.v = v.segment<2>(2);
    x.yaw = v(4);
    x.gyro_bias = v(5);
    x.accel_bias = v.segment<2>(6);
    return x;
  };
  const double eps = 1e-6;
  for (int i = 0; i < 8; ++i) {
    Eigen::Matrix<double, 8, 1> up = vec(s), down = vec(s);
    up(i) += eps;
    down(i) -= eps;
    const Eigen::Matrix<double, 8, 1> numeric =
        (vec(loc::mechanise(state(up), imu, dt)) - vec(loc::mechanise(state(down), imu, dt))) /
        (2 * eps);
    for (int r = 0; r < 8; ++r) EXPECT_NEAR(f(r, i), numeric(r), 1e-8) << r << "," << i;
  }
}

// At rest (white noise 0.05 m/s², 0.005 rad/s) the IMU is still and not turning; driving at
// constant velocity it reads the same mean but vibrates (0.3 m/s²): not still; turning in place
// at 1 rad/s it is still (no translation) but turning, so no ZARU.
TEST(Ins, StationarityDetectorsOnHandMadeSamples) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  auto feed = [&](double acc_noise, double rate) {
    loc::StationarityDetector d(0.3, 0.1, 0.02, 0.02);
    for (int k = 0; k < 60; ++k)
      d.add(sample(0.01 * k, acc_noise * n(rng), acc_noise * n(rng), rate + 0.005 * n(rng)));
    return d;
  };
  const auto rest = feed(0.05, 0.0);
  EXPECT_TRUE(rest.still());
  EXPECT_TRUE(rest.notTurning(0.0));
  EXPECT_FALSE(rest.notTurning(0.05));  // a bias estimate 0.05 off the measured rate
  EXPECT_FALSE(feed(0.3, 0.0).still());
  const auto turning = feed(0.05, 1.0);
  EXPECT_TRUE(turning.still());
  EXPECT_FALSE(turning.notTurning(0.0));
  EXPECT_NEAR(turning.meanRate(), 1.0, 0.01);
  // Too few samples for the window: not still.
  loc::StationarityDetector short_window(0.3, 0.1, 0.02, 0.02);
  for (int k = 0; k < 4; ++k) short_window.add(sample(0.01 * k, 0, 0, 0));
  EXPECT_FALSE(short_window.still());
}

// UWB/INS on the AGV room: full coverage through the 15-17 s UWB gap, ZUPT exactly while the
// robot turns in place at the corners (0.5 m/s legs, 1 rad/s turns), and the INS carrying the
// estimate through the gap better than uwb-ekf's constant-velocity prediction.
TEST(Ins, FusionOnTheAgvRoom) {
  const auto ds = test::simulatedScenario("agv_room", 1);
  const double t0 = ds.ground_truth.front().t;
  auto gapError = [&](const eval::RunResult& run) {
    double worst = 0.0;
    int n = 0;
    for (const auto& e : eval::associate(run.trajectory, ds.ground_truth))
      if (e.t - t0 > 15.0 && e.t - t0 < 17.5) {
        worst = std::max(worst, e.e2d);
        ++n;
      }
    EXPECT_GT(n, 10) << run.spec;
    return worst;
  };
  const auto ins = eval::runMethod(ds, "uwb-ins", 1);
  const auto ekf = eval::runMethod(ds, "uwb-ekf", 1);
  const auto m_ins = eval::computeMetrics(eval::associate(ins.trajectory, ds.ground_truth),
                                          ins.trajectory, ds.ground_truth);
  const auto m_ekf = eval::computeMetrics(eval::associate(ekf.trajectory, ds.ground_truth),
                                          ekf.trajectory, ds.ground_truth);
  const double gap_ins = gapError(ins), gap_ekf = gapError(ekf);
  std::printf("[ INS      ] rmse_2d uwb-ins %.3f m, uwb-ekf %.3f m; worst in the gap %.3f / %.3f m;"
              " zupt %ld\n",
              m_ins.rmse_2d, m_ekf.rmse_2d, gap_ins, gap_ekf,
              ins.statistics.events.count("zupt") ? ins.statistics.events.at("zupt") : 0L);
  EXPECT_GE(m_ins.coverage, 0.99);
  EXPECT_LT(m_ins.rmse_2d, 0.2);
  EXPECT_LT(gap_ins, gap_ekf);
  // Four corners of 90° at 1 rad/s, 150 Hz: about 4 x 1.57 s x 150 = 942 still samples (the
  // detector's window trims each end).
  ASSERT_TRUE(ins.statistics.events.count("zupt"));
  EXPECT_NEAR(ins.statistics.events.at("zupt"), 942, 100);
  EXPECT_EQ(ins.statistics.events.count("zaru"), 0u);  // it never stops turning when still
  // The cubature variant (the points through the mechanisation) tracks as the EKF does.
  const auto ckf = eval::runMethod(ds, "uwb-ins-ckf", 1);
  const double rmse_ckf = eval::computeMetrics(eval::associate(ckf.trajectory, ds.ground_truth),
                                               ckf.trajectory, ds.ground_truth)
                              .rmse_2d;
  std::printf("[ INS      ] rmse_2d uwb-ins-ckf %.3f m\n", rmse_ckf);
  EXPECT_NEAR(rmse_ckf, m_ins.rmse_2d, 0.02);
}
