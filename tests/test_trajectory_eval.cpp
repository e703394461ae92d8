// Trajectory evaluation (APE raw and aligned, RPE, heading) on constructed cases whose answers
// follow from evo's definitions by hand.
#include <gtest/gtest.h>

#include <cmath>

#include "uwbloc/evaluation/trajectory_eval.hpp"

using namespace uwbloc;
using eval::PosePair;

namespace {

// A curved reference: a quarter circle of radius 4 m then a straight leg, at 4 Hz (exact times).
std::vector<data::TimedPose> curvedReference() {
  std::vector<data::TimedPose> ref;
  for (int k = 0; k <= 120; ++k) {
    const double t = 0.25 * k;
    Eigen::Vector3d p;
    if (t <= 15.0) {
      const double a = M_PI / 2.0 * t / 15.0;
      p << 4.0 * std::sin(a), 4.0 - 4.0 * std::cos(a), a;
    } else {
      p << 4.0, 4.0 + 0.4 * (t - 15.0), M_PI / 2.0;
    }
    ref.push_back({t, p});
  }
  return ref;
}

// The reference moved by the rigid motion (tx, ty, th), as a method's estimate.
std::vector<loc::PoseEstimate> moved(const std::vector<data::TimedPose>& ref, double tx, double ty,
                                     double th) {
  std::vector<loc::PoseEstimate> est;
  for (const auto& r : ref) {
    loc::PoseEstimate e;
    e.t = r.t;
    e.pose << tx + std::cos(th) * r.pose.x() - std::sin(th) * r.pose.y(),
        ty + std::sin(th) * r.pose.x() + std::cos(th) * r.pose.y(), r.pose.z() + th;
    est.push_back(e);
  }
  return est;
}

}  // namespace

TEST(TrajectoryEval, ARigidOffsetIsRemovedByEitherAlignmentAndLeavesRpeAtZero) {
  const auto ref = curvedReference();
  const double tx = 0.5, ty = -0.2, th = 0.3;
  const auto pairs = eval::associatePoses(moved(ref, tx, ty, th), ref, {true, 1.0});
  ASSERT_EQ(pairs.size(), ref.size());
  // Raw APE by hand: |T p - p| for every reference point.
  double sq = 0.0;
  for (const auto& r : ref) {
    const double x = tx + std::cos(th) * r.pose.x() - std::sin(th) * r.pose.y() - r.pose.x();
    const double y = ty + std::sin(th) * r.pose.x() + std::cos(th) * r.pose.y() - r.pose.y();
    sq += x * x + y * y;
  }
  const double raw = std::sqrt(sq / static_cast<double>(ref.size()));
  for (auto a : {eval::Alignment::kSe2, eval::Alignment::kSe2Origin}) {
    const auto s = eval::scoreTrajectory(pairs, a, {1.0, false});
    EXPECT_NEAR(s.ape.rmse, raw, 1e-9);
    EXPECT_NEAR(s.ape_aligned.rmse, 0.0, 1e-9) << eval::toString(a);
    EXPECT_NEAR(s.ape_aligned.max, 0.0, 1e-9);
    // The alignment found is the inverse of the offset.
    EXPECT_NEAR(s.alignment.z(), -th, 1e-9);
    EXPECT_NEAR(s.yaw_deg.rmse, th * 180.0 / M_PI, 1e-9);
    EXPECT_NEAR(s.rpe.trans.max, 0.0, 1e-9);
    EXPECT_NEAR(s.rpe.rot_deg.max, 0.0, 1e-9);
    EXPECT_GT(s.rpe.trans.n, 10);
  }
  EXPECT_NEAR(eval::scoreTrajectory(pairs, eval::Alignment::kNone, {1.0, false}).ape_aligned.rmse,
              raw, 1e-12);
}

TEST(TrajectoryEval, AConstantDriftGivesItsAnalyticApeAlignedApeAndRpe) {
  // A straight reference along x at 0.4 m/s; the estimate runs 5 cm/s ahead of it.
  std::vector<data::TimedPose> ref;
  std::vector<loc::PoseEstimate> est;
  const double v = 0.4, drift = 0.05;
  for (int k = 0; k <= 80; ++k) {
    const double t = 0.25 * k;
    ref.push_back({t, {v * t, 1.0, 0.0}});
    loc::PoseEstimate e;
    e.t = t;
    e.pose << (v + drift) * t, 1.0, 0.0;
    est.push_back(e);
  }
  const auto pairs = eval::associatePoses(est, ref, {false, 0.01});
  ASSERT_EQ(pairs.size(), 81u);
  // Raw: e_k = drift t_k, RMSE = drift sqrt(mean t^2). Aligned: the best rigid motion is the
  // mean shift (no rotation: the lines are parallel), so e_k = drift |t_k - mean t|.
  double mean = 0.0, mean_sq = 0.0;
  for (const auto& p : pairs) mean += p.t, mean_sq += p.t * p.t;
  mean /= 81.0;
  mean_sq /= 81.0;
  const double var = mean_sq - mean * mean;
  for (auto [delta, expected] :
       {std::pair{eval::RpeDelta{1.0, true}, drift * 1.0},          // 1 s stretches: 5 cm each
        std::pair{eval::RpeDelta{2.0, false}, drift * 2.0 / v}}) {  // 2 m of path take 5 s
    const auto s = eval::scoreTrajectory(pairs, eval::Alignment::kSe2, delta);
    EXPECT_NEAR(s.ape.rmse, drift * std::sqrt(mean_sq), 1e-9);
    EXPECT_NEAR(s.ape.max, drift * 20.0, 1e-9);
    EXPECT_NEAR(s.ape_aligned.rmse, drift * std::sqrt(var), 1e-9);
    EXPECT_NEAR(s.alignment.z(), 0.0, 1e-12);
    EXPECT_NEAR(s.rpe.trans.rmse, expected, 1e-9) << eval::toString(delta);
    EXPECT_NEAR(s.rpe.trans.std, 0.0, 1e-9);
    EXPECT_NEAR(s.rpe.rot_deg.rmse, 0.0, 1e-12);
  }
  // Origin alignment: the first poses coincide already, so nothing changes.
  const auto o = eval::scoreTrajectory(pairs, eval::Alignment::kSe2Origin, {1.0, true});
  EXPECT_NEAR(o.ape_aligned.rmse, o.ape.rmse, 1e-12);
}

TEST(TrajectoryEval, AHeadingDriftShowsInTheRotationalRpe) {
  const auto ref = curvedReference();
  std::vector<loc::PoseEstimate> est;
  for (const auto& r : ref) {
    loc::PoseEstimate e;
    e.t = r.t;
    e.pose = r.pose;
    e.pose.z() += 0.01 * r.t;  // 0.01 rad/s of heading drift, positions exact
    est.push_back(e);
  }
  const auto pairs = eval::associatePoses(est, ref, {true, 1.0});
  const auto rpe = eval::relativePoseError(pairs, {2.0, true});
  EXPECT_NEAR(rpe.rot_deg.rmse, 0.02 * 180.0 / M_PI, 1e-9);
  EXPECT_NEAR(rpe.rot_deg.min, rpe.rot_deg.max, 1e-9);
  // A method without heading: the reference's stands in, so exact positions give no RPE.
  for (auto& e : est) e.heading_valid = false;
  const auto blind =
      eval::relativePoseError(eval::associatePoses(est, ref, {true, 1.0}), {2.0, true});
  EXPECT_NEAR(blind.trans.max, 0.0, 1e-12);
  EXPECT_EQ(blind.rot_deg.n, 0);
}

TEST(TrajectoryEval, AssociationStatisticsAndParsing) {
  std::vector<data::TimedPose> ref{{0.0, {0, 0, 0}}, {1.0, {1, 0, 0}}, {3.0, {3, 0, 0}}};
  std::vector<loc::PoseEstimate> est(4);
  est[0].t = 0.5, est[1].t = 1.02, est[2].t = 2.0, est[3].t = 3.5;
  // Interpolation within gaps of at most 1.5 s: 0.5 only (1.02 and 2.0 lie in the 2 s gap).
  // (The reference's median step, 2 s, would make it sparse at the default threshold.)
  EXPECT_EQ(eval::associatePoses(est, ref, {true, 1.5, 10.0}).size(), 1u);
  EXPECT_EQ(eval::associatePoses(est, ref, {true, 2.5, 10.0}).size(), 3u);
  // Nearest within 0.05 s: only 1.02 -> 1.0.
  const auto near = eval::associatePoses(est, ref, {false, 0.05});
  ASSERT_EQ(near.size(), 1u);
  EXPECT_DOUBLE_EQ(near[0].ref.x(), 1.0);

  const auto st = eval::errorStats({3.0, 4.0, 0.0, 1.0});
  EXPECT_EQ(st.n, 4);
  EXPECT_NEAR(st.rmse, std::sqrt(26.0 / 4.0), 1e-12);
  EXPECT_NEAR(st.mean, 2.0, 1e-12);
  EXPECT_NEAR(st.median, 2.0, 1e-12);
  EXPECT_NEAR(st.std, std::sqrt(2.5), 1e-12);  // population std, as evo's numpy
  EXPECT_NEAR(st.sse, 26.0, 1e-12);
  EXPECT_TRUE(std::isnan(eval::errorStats({}).rmse));

  EXPECT_TRUE(eval::parseRpeDelta("2s").seconds);
  EXPECT_DOUBLE_EQ(eval::parseRpeDelta("0.5 m").value, 0.5);
  EXPECT_FALSE(eval::parseRpeDelta("3").seconds);
  EXPECT_THROW(eval::parseRpeDelta("-1m"), std::invalid_argument);
  EXPECT_THROW(eval::parseRpeDelta("1km"), std::invalid_argument);
  EXPECT_THROW(eval::parseAlignment("sim3"), std::invalid_argument);
}

TEST(TrajectoryEval, ASparseReferenceIsScoredAtItsOwnStamps) {
  // The robot drives a circle of radius 2 m at 0.5 rad/s; the reference has a pose every 2 s,
  // the estimate is exact at 50 Hz. Interpolating the reference puts it on the chords, whose
  // midpoints lie r (1 - cos(w T / 2)) inside the circle; scored at the reference's stamps, the
  // exact estimate has no error (up to its own 0.02 s chords).
  const double r = 2.0, w = 0.5, step = 2.0;
  const auto on = [&](double t) {
    return Eigen::Vector3d(r * std::cos(w * t), r * std::sin(w * t), 0.0);
  };
  std::vector<data::TimedPose> ref;
  for (double t = 0.0; t <= 20.0 + 1e-9; t += step) ref.push_back({t, on(t)});
  std::vector<loc::PoseEstimate> est;
  for (int k = 0; k <= 1000; ++k) {
    loc::PoseEstimate e;
    e.t = 0.02 * k;
    e.pose = on(e.t);
    est.push_back(e);
  }
  const auto max_error = [](const std::vector<eval::PosePair>& pairs) {
    double m = 0.0;
    for (const auto& p : pairs) m = std::max(m, (p.est - p.ref).head<2>().norm());
    return m;
  };
  EXPECT_DOUBLE_EQ(eval::medianStep(ref), step);
  const auto at_stamps = eval::associatePoses(est, ref, {true, 5.0});
  ASSERT_EQ(at_stamps.size(), ref.size());
  for (size_t i = 0; i < ref.size(); ++i) EXPECT_DOUBLE_EQ(at_stamps[i].t, ref[i].t);
  EXPECT_LT(max_error(at_stamps), 1e-3);
  // The reference interpolated at the estimate's 1001 stamps (a threshold above its step).
  const auto interpolated = eval::associatePoses(est, ref, {true, 5.0, 10.0});
  ASSERT_EQ(interpolated.size(), est.size());
  EXPECT_NEAR(max_error(interpolated), r * (1.0 - std::cos(w * step / 2.0)), 1e-3);
  // A reference at 10 Hz is dense: interpolated at the estimate's stamps as before.
  std::vector<data::TimedPose> dense;
  for (int k = 0; k <= 200; ++k) dense.push_back({0.1 * k, on(0.1 * k)});
  EXPECT_EQ(eval::associatePoses(est, dense, {true, 5.0}).size(), est.size());
  // An estimate with a gap longer than max_diff is not interpolated across it.
  std::vector<loc::PoseEstimate> gappy;
  for (const auto& e : est)
    if (e.t < 5.0 || e.t > 11.0) gappy.push_back(e);
  EXPECT_EQ(eval::associatePoses(gappy, ref, {true, 5.0}).size(), ref.size() - 3);
}

// An estimator that reports at the sparse reference's own rate, but at other stamps (each
// odometry step 1.06 s apart, 0.3 s after the reference's), is paired at every reference stamp
// that two estimates bracket; a gap of four of the reference's steps is still not bridged.
TEST(TrajectoryEval, EstimatesAtASparseReferencesRateButOtherStampsPair) {
  const double step = 1.06;
  std::vector<data::TimedPose> ref;
  for (int k = 0; k <= 20; ++k) ref.push_back({step * k, Eigen::Vector3d(0.5 * step * k, 0, 0)});
  std::vector<loc::PoseEstimate> est;
  for (int k = -1; k <= 20; ++k) {
    loc::PoseEstimate e;
    e.t = step * k + 0.3;
    e.pose = Eigen::Vector3d(0.5 * e.t, 0.0, 0.0);  // the same straight drive at 0.5 m/s
    est.push_back(e);
  }
  const auto pairs = eval::associatePoses(est, ref, {true, 1.0});
  ASSERT_EQ(pairs.size(), ref.size());
  for (const auto& p : pairs) EXPECT_NEAR((p.est - p.ref).norm(), 0.0, 1e-9) << p.t;
  const std::string said = eval::describePairing(ref, {true, 1.0});
  EXPECT_NE(said.find("at most 1.59 s apart"), std::string::npos) << said;
  // Without the estimates at 4.54, 5.60 and 6.66 s (a 4.24 s gap from 3.48 to 7.72 s): the four
  // reference stamps within it (4.24, 5.30, 6.36 and 7.42 s) are not scored.
  std::vector<loc::PoseEstimate> gappy;
  for (const auto& e : est)
    if (e.t < 4.0 || e.t > 7.0) gappy.push_back(e);
  EXPECT_EQ(eval::associatePoses(gappy, ref, {true, 1.0}).size(), ref.size() - 4);
}

// The table's footer says which pairing scored the run: the reference's own stamps for a sparse
// one, the interpolated reference for a dense one, the nearest pose when asked.
TEST(TrajectoryEval, ThePairingIsDescribedAsItWasDone) {
  std::vector<data::TimedPose> sparse, dense;
  for (int k = 0; k <= 10; ++k) sparse.push_back({2.0 * k, Eigen::Vector3d::Zero()});
  for (int k = 0; k <= 100; ++k) dense.push_back({0.1 * k, Eigen::Vector3d::Zero()});
  const auto has = [](const std::string& text, const char* part) {
    return text.find(part) != std::string::npos;
  };
  const std::string at_stamps = eval::describePairing(sparse, {true, 1.0});
  EXPECT_TRUE(has(at_stamps, "at the reference's own stamps")) << at_stamps;
  EXPECT_TRUE(has(at_stamps, "2.00 s")) << at_stamps;
  EXPECT_TRUE(has(eval::describePairing(dense, {true, 1.0}), "interpolated at each estimate"));
  EXPECT_TRUE(has(eval::describePairing(sparse, {true, 1.0, 10.0}), "interpolated at each"));
  EXPECT_TRUE(has(eval::describePairing(sparse, {false, 0.01}), "nearest reference pose"));
}
