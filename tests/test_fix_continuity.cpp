// Fault exclusion by continuity (fix_continuity.hpp): two anchors on a line and a third whose
// wrong range fits the mirror image of the tag exactly, as the MRPT demo's beacon 1 does.
#include <gtest/gtest.h>

#include <cmath>

#include "uwbloc/localization/fix_continuity.hpp"
#include "uwbloc/uwb/multilateration.hpp"

using namespace uwbloc;

namespace {

const Eigen::Vector2d kA1(-6.0, -4.0), kA2(0.0, 0.0), kA3(0.0, 5.0);  // A2, A3 on x = 0

uwb::PlanarRange range(const Eigen::Vector2d& anchor, const Eigen::Vector2d& at) {
  return {anchor, (at - anchor).norm(), 0.1};
}

// The epoch at `tag`, with A1's range taken at the tag's mirror in x = 0 when `faulty`.
std::vector<uwb::PlanarRange> epoch(const Eigen::Vector2d& tag, bool faulty) {
  const Eigen::Vector2d mirror(-tag.x(), tag.y());
  return {range(kA1, faulty ? mirror : tag), range(kA2, tag), range(kA3, tag)};
}

uwb::Fix gaussNewton(const std::vector<uwb::PlanarRange>& r) { return uwb::solveGaussNewton(r); }

}  // namespace

TEST(CircleIntersections, TwoPointsOneOnTheCentreLineOrNone) {
  const auto two = uwb::circleIntersections({{0, 0}, 5.0, 0.1}, {{8, 0}, 5.0, 0.1});
  ASSERT_EQ(two.size(), 2u);
  EXPECT_NEAR(two[0].x(), 4.0, 1e-12);
  EXPECT_NEAR(std::abs(two[0].y()), 3.0, 1e-12);
  EXPECT_NEAR(two[1].y(), -two[0].y(), 1e-12);
  // Apart by 1 m: the point on the line between the anchors, where 2 r1 x = r1^2 - r2^2 + D^2.
  const auto apart = uwb::circleIntersections({{0, 0}, 3.0, 0.1}, {{8, 0}, 4.0, 0.1});
  ASSERT_EQ(apart.size(), 1u);
  EXPECT_NEAR(apart[0].x(), (9.0 - 16.0 + 64.0) / 16.0, 1e-12);
  EXPECT_NEAR(apart[0].y(), 0.0, 1e-12);
  EXPECT_TRUE(uwb::circleIntersections({{1, 1}, 3.0, 0.1}, {{1, 1}, 4.0, 0.1}).empty());
}

TEST(FixContinuity, TheMirrorFixIsReplacedByTheReachablePositionAndTheWrongRangeLeftOut) {
  loc::FixContinuity continuity;
  // The tag drives along y at x = 5, 0.5 m/s, one epoch per second; A1 turns faulty at t = 5.
  int excluded = 0;
  for (int k = 0; k <= 20; ++k) {
    const double t = k;
    const Eigen::Vector2d tag(5.0, -2.0 + 0.5 * t);
    const auto ranges = epoch(tag, k >= 5);
    const uwb::Fix fix = uwb::solveGaussNewton(ranges);
    ASSERT_TRUE(fix.ok());
    if (k >= 5) {
      // The faulty epoch fits the mirror exactly: no residual tells it from the truth.
      EXPECT_NEAR(fix.position.x(), -5.0, 0.05) << "t " << t;
      EXPECT_LT(fix.residual_norm, 0.01);
    }
    const auto checked = continuity.check(t, fix, ranges, gaussNewton);
    ASSERT_TRUE(checked.fix) << "t " << t;
    EXPECT_LT((checked.fix->position - tag).norm(), 0.05) << "t " << t;
    if (k < 5) {
      EXPECT_EQ(checked.outcome, loc::Continuity::kAsIs);
    } else {
      EXPECT_EQ(checked.outcome, loc::Continuity::kExcluded);
      ASSERT_EQ(checked.left_out.size(), 1u);
      EXPECT_EQ(checked.left_out[0], 0);  // A1
      ++excluded;
    }
  }
  EXPECT_EQ(excluded, 16);
}

TEST(FixContinuity, TheStartPoseDecidesTheFirstFix) {
  const Eigen::Vector2d tag(5.0, 1.0);
  const auto ranges = epoch(tag, true);
  const uwb::Fix fix = uwb::solveGaussNewton(ranges);
  loc::FixContinuity unseeded;
  EXPECT_NEAR(unseeded.check(0.0, fix, ranges, gaussNewton).fix->position.x(), -5.0, 0.05);
  loc::FixContinuity seeded;
  seeded.seed(-1.0, {4.5, 1.0});
  const auto checked = seeded.check(0.0, fix, ranges, gaussNewton);
  ASSERT_TRUE(checked.fix);
  EXPECT_EQ(checked.outcome, loc::Continuity::kExcluded);
  EXPECT_LT((checked.fix->position - tag).norm(), 0.05);
}

TEST(FixContinuity, NothingReachableIsRefusedThenTheFixRestartsTheTrack) {
  loc::FixContinuityParams params;
  params.max_unreachable = 3;
  loc::FixContinuity continuity(params);
  continuity.seed(0.0, {50.0, 50.0});  // far from anything the ranges allow
  const Eigen::Vector2d tag(5.0, 1.0);
  for (int k = 1; k <= 3; ++k) {
    const auto ranges = epoch(tag, false);
    const auto checked =
        continuity.check(0.01 * k, uwb::solveGaussNewton(ranges), ranges, gaussNewton);
    if (k < 3) {
      EXPECT_EQ(checked.outcome, loc::Continuity::kUnreachable);
      EXPECT_FALSE(checked.fix);
    } else {
      EXPECT_EQ(checked.outcome, loc::Continuity::kRestart);
      ASSERT_TRUE(checked.fix);
      EXPECT_LT((checked.fix->position - tag).norm(), 0.05);
    }
  }
}
