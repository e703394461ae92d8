// Cramér–Rao bounds: analytic values, a multilateration solver that reaches the static bound
// on a simulated static tag, and the posterior bound's behaviour.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>

#include "simulated_scenario.hpp"
#include "test_helpers.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/bounds.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"

using namespace uwbloc;


TEST(StaticCrlb, AnalyticValues) {
  // Four anchors at the tag's height, tag in the centre: J = 2/sigma^2 I, trace(J^-1) = sigma^2.
  const std::vector<uwb::Anchor> square{
      {1, {0, 0, 1}}, {2, {4, 0, 1}}, {3, {4, 4, 1}}, {4, {0, 4, 1}}};
  const auto c = eval::staticCrlb(square, {2, 2}, 1.0, 0.1);
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->trace(), 0.01, 1e-12);
  EXPECT_NEAR((*c)(0, 1), 0.0, 1e-12);
  // A height difference makes each range less informative about (x, y): u = d_xy / d_3d.
  const std::vector<uwb::Anchor> high{
      {1, {0, 0, 3}}, {2, {4, 0, 3}}, {3, {4, 4, 3}}, {4, {0, 4, 3}}};
  const double r2 = 8.0, h2 = 4.0;  // squared planar distance and height difference
  EXPECT_NEAR(eval::staticCrlb(high, {2, 2}, 1.0, 0.1)->trace(), 0.01 * (r2 + h2) / r2, 1e-12);
  // Tag on the line through the only two anchors: the cross-line direction is unobserved.
  const std::vector<uwb::Anchor> line{{1, {0, 0, 1}}, {2, {4, 0, 1}}};
  EXPECT_FALSE(eval::staticCrlb(line, {2, 0}, 1.0, 0.1));
  EXPECT_TRUE(eval::staticCrlb(line, {2, 2}, 1.0, 0.1));
}

TEST(StaticCrlb, SeveralTagsOnOneRobot) {
  const std::vector<uwb::Anchor> square{
      {1, {0, 0, 1}}, {2, {4, 0, 1}}, {3, {4, 4, 1}}, {4, {0, 4, 1}}};
  const Eigen::Vector3d pose(2, 2, 0.3);
  // Three tags at the robot's origin: three times one tag's information, and none on the heading.
  const Eigen::Vector3d origin(0, 0, 1);
  const auto same = eval::staticCrlbOfPose(square, pose, {origin, origin, origin}, 0.1);
  ASSERT_TRUE(same);
  EXPECT_NEAR(same->trace(), 0.01 / 3.0, 1e-12);
  // One tag at the origin is staticCrlb's tag.
  EXPECT_NEAR(eval::staticCrlbOfPose(square, pose, {origin}, 0.1)->trace(), 0.01, 1e-12);
  // Three tags 0.3 m apart (multitag_room's): the heading is unknown too, so the position is
  // bounded between three tags at one place and one tag.
  const std::vector<Eigen::Vector3d> spread{{-0.07, -0.14, 1}, {-0.075, 0.14, 1}, {0.2, 0.145, 1}};
  const auto apart = eval::staticCrlbOfPose(square, pose, spread, 0.1);
  ASSERT_TRUE(apart);
  EXPECT_GT(apart->trace(), 0.01 / 3.0);
  EXPECT_LT(apart->trace(), 0.01);
}

namespace {

// `method` on the simulated `scenario` (seed `seed`) against the static bound: its metrics, the
// bound's RMS and their ratio, printed.
struct Efficiency {
  eval::Metrics metrics;
  double bound = 0.0;
  double ratio = 0.0;
};
Efficiency staticEfficiency(const std::string& scenario, uint64_t seed, const std::string& method) {
  const auto ds = test::simulatedScenario(scenario, seed);
  const auto run = eval::runMethod(ds, method, 1);
  Efficiency e;
  e.metrics = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth), run.trajectory,
                                   ds.ground_truth);
  e.bound = eval::computeBounds(ds).static_rmse;
  e.ratio = e.metrics.rmse_2d / e.bound;
  std::printf("[ CRLB     ] %s: %s, %ld epochs, rmse %.4f m, sqrt(CRLB) %.4f m, efficiency %.3f\n",
              scenario.c_str(), method.c_str(), e.metrics.steps, e.metrics.rmse_2d, e.bound,
              e.ratio);
  return e;
}

}  // namespace

TEST(StaticCrlb, TheThreeTagSolverIsEfficientOnMultitagRoom) {
  // Each epoch's pose from the three tags' ranges at once (uwb-multitag, unfiltered) against the
  // bound of that epoch's ranges, the heading unknown: one tag's bound, which the report gave
  // before, sits far above what three tags reach.
  const Efficiency e = staticEfficiency("multitag_room", 5, "uwb-multitag:smooth=false");
  EXPECT_GE(e.ratio, 0.9);
  EXPECT_LE(e.ratio, 1.2);
}

TEST(StaticCrlb, GaussNewtonIsEfficientOnAStaticLosTag) {
  const Efficiency e = staticEfficiency("static_los", 21, "uwb-gn");
  EXPECT_EQ(e.metrics.steps, 1000);
  EXPECT_GE(e.ratio, 0.9);
  EXPECT_LE(e.ratio, 1.1);
}

TEST(PosteriorCrlb, AccumulatesInformation) {
  const auto ds = test::simulatedScenario("static_los", 3);
  const auto pcrb = eval::posteriorCrlb(ds, *ds.manifest.bounds);
  const auto crlb = eval::staticCrlbSeries(ds, ds.manifest.bounds->range_sigma);
  ASSERT_GT(pcrb.t.size(), 100u);
  // Below the single-epoch bound once a few epochs are in (the CV model's process noise keeps
  // it from shrinking to zero), and never rising while static.
  EXPECT_LT(pcrb.mean(5.0), 0.75 * crlb.mean());
  for (size_t i = 40; i < pcrb.position_variance.size(); i += 40)
    EXPECT_LE(pcrb.position_variance[i], pcrb.position_variance[i - 40] * 1.0001) << i;
  // With odometry as the motion model the bound uses the heading too, and stays finite.
  data::BoundsSpec odo = *ds.manifest.bounds;
  odo.motion = "odometry";
  const auto with_odo = eval::posteriorCrlb(test::simulatedScenario("tracking_los", 3), odo);
  EXPECT_TRUE(std::isfinite(with_odo.mean(5.0)));
}

TEST(PosteriorCrlb, TrackingEfficiencyIsReported) {
  const auto ds = test::simulatedScenario("tracking_los", 4);
  const auto bounds = eval::computeBounds(ds);
  double best = 1e9;
  std::string best_name;
  for (const char* m : {"uwb-kf", "uwb-ekf"}) {
    const auto s = eval::evaluateMethod(ds, m, 1, 1);
    if (s.metrics.rmse_2d < best) {
      best = s.metrics.rmse_2d;
      best_name = m;
    }
  }
  std::printf(
      "[ PCRB     ] tracking_los: best filter %s rmse %.4f m; sqrt(PCRB, cv q=%.2f) %.4f m, "
      "efficiency %.2f; sqrt(static CRLB) %.4f m\n",
      best_name.c_str(), best, ds.manifest.bounds->accel_psd, bounds.posterior_rmse,
      best / bounds.posterior_rmse, bounds.static_rmse);
  EXPECT_TRUE(std::isfinite(bounds.posterior_rmse));
  EXPECT_LT(best, bounds.static_rmse);  // filtering beats single epochs
}
