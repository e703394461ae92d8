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

namespace {

// A tag driving at 0.4 m/s along y = 2 away from x = 0 (the line of A2 and A3) while A1 reads
// `short_by` short from t = 4 on (the MRPT demo's beacon 1 after its range wraps), with A1's range
// lost at t = 4 (an epoch of two ranges). Returns the largest error of the kept fixes, and how
// many epochs gave none.
std::pair<double, int> crossTheLine(const loc::FixContinuityParams& params, double short_by) {
  loc::FixContinuity continuity(params);
  double worst = 0.0;
  int none = 0;
  for (int k = 0; k <= 15; ++k) {
    const double t = k;
    const Eigen::Vector2d tag(0.5 + 0.4 * t, 2.0);
    auto ranges = epoch(tag, false);
    if (k >= 4) ranges[0].range -= short_by;
    loc::FixContinuity::Checked checked;
    if (k == 4) {
      checked = continuity.checkTwo(t, {ranges[1], ranges[2]});
      if (params.track) {
        EXPECT_EQ(checked.outcome, loc::Continuity::kTwoRanges);
      }
    } else {
      checked = continuity.check(t, uwb::solveGaussNewton(ranges), ranges, gaussNewton);
    }
    if (!checked.fix) {
      ++none;
      continue;
    }
    worst = std::max(worst, (checked.fix->position - tag).norm());
  }
  return {worst, none};
}

}  // namespace

TEST(FixContinuity, ASlowTagIsTrackedFromTheGoodPairsLineWhileTheThirdRangeReadsShort) {
  // The track's acceleration density as the range front end sets it on the MRPT demo (twice the
  // learnt path's 0.1 m^2/s^3), whose beacon 1 reads 3-4 m short for tens of seconds.
  loc::FixContinuityParams params;
  params.accel_psd = 0.2;
  for (double short_by : {3.0, 4.0}) {
    // Every epoch has a fix, on the tag; the epoch of two ranges keeps the track.
    const auto [worst, none] = crossTheLine(params, short_by);
    EXPECT_EQ(none, 0) << short_by;
    EXPECT_LT(worst, 0.1) << short_by;
  }
  // The speed bound alone lets the short range's fix in: metres off.
  params.track = false;
  EXPECT_GT(crossTheLine(params, 3.0).first, 1.0);
}

TEST(FixContinuity, TwoRangesNeedATrackedVelocity) {
  const Eigen::Vector2d tag(5.0, 1.0);
  const auto ranges = epoch(tag, false);
  loc::FixContinuity continuity;
  // Nothing kept yet: the two circles' intersections are a coin toss, none is taken.
  EXPECT_FALSE(continuity.checkTwo(0.0, {ranges[1], ranges[2]}).fix);
  continuity.seed(0.0, tag);
  EXPECT_FALSE(continuity.checkTwo(1.0, {ranges[1], ranges[2]}).fix);  // a position, no velocity
  continuity.check(1.0, uwb::solveGaussNewton(ranges), ranges, gaussNewton);
  const auto two = continuity.checkTwo(2.0, {ranges[1], ranges[2]});
  ASSERT_TRUE(two.fix);
  EXPECT_LT((two.fix->position - tag).norm(), 1e-6);  // not the mirror at x = -5
}

TEST(FixContinuity, ARangeLeftOutStaysOutUntilItAgreesWithTheTrackAgain) {
  loc::FixContinuityParams params;
  params.accel_psd = 0.2;
  loc::FixContinuity continuity(params);
  // A1 reads 3 m short at t = 4-6, then 1.5 m short at t = 7-8 (recovering, as the MRPT demo's
  // beacon 1 does), then right.
  for (int k = 0; k <= 10; ++k) {
    const double t = k;
    const Eigen::Vector2d tag(2.0 + 0.4 * t, 2.0);
    auto ranges = epoch(tag, false);
    const double short_by = k >= 4 && k <= 6 ? 3.0 : (k >= 7 && k <= 8 ? 1.5 : 0.0);
    ranges[0].range -= short_by;
    const uwb::Fix fix = uwb::solveGaussNewton(ranges);
    if (k == 7) {
      // The recovering range's fix is off by decimetres: inside the track's gate on its own.
      EXPECT_GT((fix.position - tag).norm(), 0.3);
    }
    const auto checked = continuity.check(t, fix, ranges, gaussNewton);
    ASSERT_TRUE(checked.fix) << "t " << t;
    EXPECT_LT((checked.fix->position - tag).norm(), 0.1) << "t " << t;
    if (short_by > 0.0) {
      EXPECT_EQ(checked.outcome, loc::Continuity::kExcluded) << "t " << t;
      ASSERT_EQ(checked.left_out.size(), 1u);
      EXPECT_EQ(checked.left_out[0], 0);
    } else {
      EXPECT_EQ(checked.outcome, loc::Continuity::kAsIs) << "t " << t;
    }
  }
}

TEST(FixContinuity, EveryRangeMustAgreeWhenTheSolverStartsFromTheLastPose) {
  // A solver started from the last pose that a wrong range pulls only 0.2 m (uwb-multitag's
  // Huber fit): the fix is inside the track's gate; only the range itself tells.
  auto run = [](bool every_range) {
    loc::FixContinuityParams params;
    params.accel_psd = 0.2;
    params.every_range = every_range;
    loc::FixContinuity continuity(params);
    loc::FixContinuity::Checked last;
    for (int k = 0; k <= 5; ++k) {
      const Eigen::Vector2d tag(2.0 + 0.4 * k, 2.0);
      auto ranges = epoch(tag, false);
      uwb::Fix fix = uwb::solveGaussNewton(ranges);
      if (k == 5) {
        ranges[0].range -= 3.0;
        fix.position += Eigen::Vector2d(-0.2, 0.0);
      }
      last = continuity.check(k, fix, ranges, gaussNewton);
    }
    return last;
  };
  const auto judged = run(true);
  EXPECT_EQ(judged.outcome, loc::Continuity::kExcluded);
  ASSERT_EQ(judged.left_out.size(), 1u);
  EXPECT_EQ(judged.left_out[0], 0);
  ASSERT_TRUE(judged.fix);
  EXPECT_LT((judged.fix->position - Eigen::Vector2d(4.0, 2.0)).norm(), 0.05);
  EXPECT_EQ(run(false).outcome, loc::Continuity::kAsIs);
}

// The track's motion (what deskewRanges moves ranges along): none before a velocity, the kept
// fixes' velocity after, and none again when that velocity is faster than the plausible speed.
TEST(FixContinuity, TheTracksMotionIsItsVelocityWhilePlausible) {
  loc::FixContinuityParams params;
  params.max_speed = 2.0;
  params.floor = 3.0;  // every fix below is reachable
  loc::FixContinuity slow(params), fast(params);
  for (int k = 0; k <= 10; ++k) {
    const double t = 0.5 * k;
    for (auto [c, speed] : {std::pair{&slow, 1.0}, std::pair{&fast, 4.0}}) {
      const auto ranges = epoch(Eigen::Vector2d(speed * t, 0.0), false);
      ASSERT_TRUE(c->check(t, uwb::solveGaussNewton(ranges), ranges, gaussNewton).fix);
    }
    if (k == 0) {
      EXPECT_FALSE(slow.motion(t + 0.5)) << "one fix: no velocity yet";
    }
  }
  const auto motion = slow.motion(5.5);
  ASSERT_TRUE(motion);
  EXPECT_NEAR(motion->velocity.x(), 1.0, 0.05);
  EXPECT_NEAR(motion->velocity.y(), 0.0, 0.05);
  EXPECT_NEAR(motion->position.x(), 5.5, 0.05);
  EXPECT_FALSE(fast.motion(5.5)) << "4 m/s against a plausible 2 m/s";
  EXPECT_FALSE(slow.motion(5.0 + params.velocity_span + 0.1)) << "the velocity is forgotten";
}
