// Evaluation: interpolation, association and metrics against hand-computed values.
#include <gtest/gtest.h>

#include <cmath>

#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/report.hpp"

using namespace uwbloc;

namespace {
std::vector<data::TimedPose> straightLine() {
  std::vector<data::TimedPose> gt;
  for (int i = 0; i <= 10; ++i) gt.push_back({static_cast<double>(i), {1.0 * i, 0.0, 0.0}});
  return gt;
}
loc::PoseEstimate at(double t, double x, double y) {
  loc::PoseEstimate e;
  e.t = t;
  e.pose << x, y, 0.0;
  return e;
}
}  // namespace

TEST(Interpolation, LinearAndAngleOnTheShortArc) {
  std::vector<data::TimedPose> gt{{0.0, {0, 0, 3.0}}, {2.0, {2, 4, -3.0}}};
  const auto p = eval::interpolateGroundTruth(gt, 1.0, 5.0);
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->x(), 1.0, 1e-12);
  EXPECT_NEAR(p->y(), 2.0, 1e-12);
  // Halfway from 3.0 to -3.0 rad across pi, not through 0.
  EXPECT_NEAR(std::abs(p->z()), M_PI, 1e-9);
  EXPECT_FALSE(eval::interpolateGroundTruth(gt, 1.0, 1.5));  // gap too long
  EXPECT_FALSE(eval::interpolateGroundTruth(gt, -0.1, 5.0));
  EXPECT_FALSE(eval::interpolateGroundTruth(gt, 2.1, 5.0));
}

TEST(Metrics, ConstantOffsetGivesAnalyticValues) {
  const auto gt = straightLine();
  std::vector<loc::PoseEstimate> est;
  for (int i = 0; i < 20; ++i) est.push_back(at(0.5 * i, 0.5 * i + 0.3, 0.4));  // 3-4-5 offset
  const auto errors = eval::associate(est, gt);
  const auto m = eval::computeMetrics(errors, est, gt);
  EXPECT_EQ(m.associated, 20);
  EXPECT_NEAR(m.rmse_x, 0.3, 1e-12);
  EXPECT_NEAR(m.rmse_y, 0.4, 1e-12);
  EXPECT_NEAR(m.rmse_2d, 0.5, 1e-12);
  EXPECT_NEAR(m.mae_2d, 0.5, 1e-12);
  EXPECT_NEAR(m.median_2d, 0.5, 1e-12);
  EXPECT_NEAR(m.max_2d, 0.5, 1e-12);
  EXPECT_NEAR(m.coverage, 1.0, 1e-12);
  ASSERT_EQ(m.cdf.size(), 21u);
  EXPECT_DOUBLE_EQ(m.cdf.back().second, 1.0);
}

TEST(Metrics, QuantilesAndCoverage) {
  EXPECT_DOUBLE_EQ(eval::quantile({4, 1, 3, 2, 5}, 0.5), 3.0);
  EXPECT_DOUBLE_EQ(eval::quantile({1, 2}, 0.95), 1.95);
  const auto gt = straightLine();  // 11 samples at 0..10 s
  std::vector<loc::PoseEstimate> est{at(0.2, 0.2, 0), at(1.0, 1, 0), at(2.5, 2.5, 0)};
  const auto m = eval::computeMetrics(eval::associate(est, gt), est, gt, 0.6);
  // Covered: 0, 1, 2, 3 (2.5 is 0.5 from both 2 and 3).
  EXPECT_NEAR(m.coverage, 4.0 / 11.0, 1e-12);
  EXPECT_NEAR(m.rmse_2d, 0.0, 1e-12);
}

TEST(Report, FileLabelsAndTum) {
  EXPECT_EQ(eval::fileLabel("uwb-kf:q=0.1,sigma=0.2"), "uwb-kf_q-0.1_sigma-0.2");
  const std::string tum = eval::formatTrajectoryTum({at(1.5, 2.0, 3.0)});
  EXPECT_EQ(tum, "1.500000000 2.000000 3.000000 0 0 0 0.000000000 1.000000000\n");
}
