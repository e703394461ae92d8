// Several tags on one robot: the manifest's tag list and bias file, the per-epoch pose solver
// (uwb-multitag), heading from geometry without motion, range calibration, and the LIAS-CUHKSZ
// importer on the shared recordings.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <random>
#include <set>
#include <tuple>

#include "simulated_scenario.hpp"
#include "test_helpers.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/lias_import.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/evaluation/calibration.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/methods/uwb_ekf.hpp"
#include "uwbloc/localization/methods/uwb_multitag.hpp"
#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc {
namespace {

const std::vector<Eigen::Vector3d> kAnchors = {{0, 0, 1.5}, {8, 0, 1.5}, {8, 8, 1.5}, {0, 8, 1.5}};
const std::vector<Eigen::Vector3d> kTags = {
    {-0.07, -0.14, 1.0}, {-0.075, 0.14, 1.0}, {0.20, 0.145, 1.0}};

// One epoch of exact ranges from the given tags at `pose`.
std::vector<loc::AcceptedRange> epochAt(const Eigen::Vector3d& pose, const std::vector<int>& tags) {
  std::vector<loc::AcceptedRange> epoch;
  for (int k : tags)
    for (size_t a = 0; a < kAnchors.size(); ++a) {
      loc::AcceptedRange r;
      r.measurement.tag_id = k;
      r.measurement.anchor_id = static_cast<int>(a);
      r.measurement.tag_on_robot = kTags[static_cast<size_t>(k)];
      r.anchor = kAnchors[a];
      r.measurement.range = uwb::predictRange(pose, r.measurement.tag_on_robot, r.anchor);
      const double dz = r.anchor.z() - r.measurement.tag_on_robot.z();
      r.planar = std::sqrt(r.measurement.range * r.measurement.range - dz * dz);
      epoch.push_back(r);
    }
  return epoch;
}

TEST(Multitag, SolvesAnEpochExactlyFromNoStart) {
  for (double deg : {-170.0, -60.0, 10.0, 95.0, 179.0}) {
    const Eigen::Vector3d truth(3.2, 5.1, deg * M_PI / 180.0);
    const auto fix = loc::solveMultitag(epochAt(truth, {0, 1, 2}), 0.1, 2.0, 20, std::nullopt);
    ASSERT_TRUE(fix.has_value()) << deg;
    EXPECT_NEAR(fix->pose.x(), truth.x(), 1e-6) << deg;
    EXPECT_NEAR(fix->pose.y(), truth.y(), 1e-6) << deg;
    EXPECT_NEAR(wrapAngle(fix->pose.z() - truth.z()), 0.0, 1e-6) << deg;
    EXPECT_EQ(fix->tags, 3);
    // Two tags are enough for the heading.
    const auto two = loc::solveMultitag(epochAt(truth, {0, 2}), 0.1, 2.0, 20, std::nullopt);
    ASSERT_TRUE(two.has_value()) << deg;
    EXPECT_NEAR(wrapAngle(two->pose.z() - truth.z()), 0.0, 1e-6) << deg;
  }
}

// The covariance is (J^T J)^-1 sigma^2: checked against the numeric Jacobian of the ranges.
TEST(Multitag, CovarianceMatchesTheNumericJacobian) {
  const Eigen::Vector3d truth(2.0, 6.0, 0.7);
  const auto epoch = epochAt(truth, {0, 1, 2});
  const double sigma = 0.1;
  const auto fix = loc::solveMultitag(epoch, sigma, 1e9, 20, truth);
  ASSERT_TRUE(fix.has_value());
  Eigen::MatrixXd j(epoch.size(), 3);
  for (size_t i = 0; i < epoch.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d plus = truth, minus = truth;
      plus(c) += 1e-6;
      minus(c) -= 1e-6;
      j(static_cast<long>(i), c) =
          (uwb::predictRange(plus, epoch[i].measurement.tag_on_robot, epoch[i].anchor) -
           uwb::predictRange(minus, epoch[i].measurement.tag_on_robot, epoch[i].anchor)) /
          2e-6;
    }
  const Eigen::Matrix3d jtj = j.transpose() * j;
  const Eigen::Matrix3d expected = jtj.inverse() * sigma * sigma;
  EXPECT_LT((fix->covariance - expected).norm(), 1e-6 * expected.norm());
}

TEST(Multitag, OneTagKeepsTheGivenHeading) {
  const Eigen::Vector3d truth(4.0, 3.0, 1.0);
  const auto fix =
      loc::solveMultitag(epochAt(truth, {2}), 0.1, 2.0, 20, Eigen::Vector3d(3.8, 3.3, 1.0));
  ASSERT_TRUE(fix.has_value());
  EXPECT_EQ(fix->tags, 1);
  EXPECT_NEAR(fix->pose.z(), 1.0, 1e-12);
  EXPECT_NEAR((fix->pose.head<2>() - truth.head<2>()).norm(), 0.0, 1e-6);
  EXPECT_DOUBLE_EQ(fix->covariance(2, 2), M_PI * M_PI);
}

// The heading error of `method` on `ds` from 1 s after its first estimate while the robot still
// stands (until 9.5 s): every estimate there must be finite and have a heading.
struct StandingHeading {
  double mean_deg = 0.0, worst_deg = 0.0;
  double worst_after = 0.0;  ///< when the worst error was, after the first estimate [s]
  long n = 0;
};
StandingHeading headingWhileStanding(const data::Dataset& ds, const std::string& method) {
  const auto run = eval::runMethod(ds, method, 1);
  StandingHeading h;
  EXPECT_FALSE(run.trajectory.empty()) << method;
  if (run.trajectory.empty()) return h;
  const double t0 = run.trajectory.front().t;
  double sum = 0.0;
  for (const auto& e : run.trajectory) {
    EXPECT_TRUE(e.pose.allFinite() && e.covariance.allFinite()) << method << " " << e.t;
    if (e.t < t0 + 1.0 || e.t > ds.start_time + 9.5) continue;
    const auto truth = eval::interpolateGroundTruth(ds.ground_truth, e.t, 1.0);
    EXPECT_TRUE(truth.has_value()) << e.t;
    EXPECT_TRUE(e.heading_valid) << method << " " << e.t;
    if (!truth || !e.heading_valid) continue;
    const double err = std::abs(wrapAngle(e.pose.z() - truth->z())) * 180.0 / M_PI;
    if (err > h.worst_deg) {
      h.worst_deg = err;
      h.worst_after = e.t - t0;
    }
    sum += err;
    ++h.n;
  }
  h.mean_deg = h.n > 0 ? sum / static_cast<double>(h.n) : 0.0;
  return h;
}

// The robot stands still for the first 10 s: with three tags the heading is known within a
// second of the first estimate, with no start pose given; a single-tag filter has none.
TEST(Multitag, HeadingConvergesWithinOneSecondWithoutMotion) {
  const data::Dataset ds = test::simulatedScenario("multitag_room", 1);
  ASSERT_EQ(ds.manifest.tags.size(), 3u);
  const auto h = headingWhileStanding(ds, "uwb-multitag");
  std::printf(
      "[ HEADING  ] uwb-multitag, standing still, 1 s after its first estimate: mean "
      "|heading error| %.2f deg, worst %.2f deg over %ld estimates\n",
      h.mean_deg, h.worst_deg, h.n);
  EXPECT_GT(h.n, 50);
  EXPECT_LT(h.mean_deg, 5.0);
  EXPECT_LT(h.worst_deg, 15.0);
  // The single-tag filter (uwb-ekf on its primary tag: the others are counted as secondary_tag)
  // has no heading while the robot stands still.
  const auto ekf = eval::runMethod(ds, "uwb-ekf:tags=primary", 1);
  EXPECT_GT(ekf.statistics.rejected.at("secondary_tag"), 0);
  for (const auto& e : ekf.trajectory) {
    if (e.t < ds.start_time + 9.5) {
      EXPECT_FALSE(e.heading_valid) << e.t;
    }
  }
}

// uwb-ekf's multi-tag range model: its Jacobian against central differences, at headings all
// round and for each tag (the heading's column carries the lever arm).
TEST(UwbEkfMultitag, RangeJacobianMatchesNumeric) {
  for (double deg : {-150.0, -30.0, 0.0, 75.0, 170.0})
    for (const auto& tag : kTags) {
      loc::UwbEkfMultitag::State x;
      x << 3.1, 4.7, 0.4, -0.2, deg * M_PI / 180.0, 0.3;
      const Eigen::Vector3d anchor = kAnchors[2];
      Eigen::Matrix<double, 1, 6> analytic;
      const double h = loc::UwbEkfMultitag::rangeModel(x, tag, anchor, &analytic);
      EXPECT_NEAR(h, uwb::predictRange({x(0), x(1), x(4)}, tag, anchor), 1e-12);
      for (int c = 0; c < 6; ++c) {
        loc::UwbEkfMultitag::State plus = x, minus = x;
        plus(c) += 1e-6;
        minus(c) -= 1e-6;
        const double numeric = (loc::UwbEkfMultitag::rangeModel(plus, tag, anchor) -
                                loc::UwbEkfMultitag::rangeModel(minus, tag, anchor)) /
                               2e-6;
        EXPECT_NEAR(analytic(c), numeric, 1e-7) << deg << " column " << c;
      }
    }
}

// multitag_room without its third tag.
data::Dataset twoTagRoom() {
  data::Dataset ds = test::simulatedScenario("multitag_room", 1);
  EXPECT_EQ(ds.manifest.tags.count(3), 1u);
  ds.manifest.tags.erase(3);
  ds.events.erase(std::remove_if(ds.events.begin(), ds.events.end(),
                                 [](const loc::Event& e) {
                                   const auto* r = std::get_if<uwb::Range>(&e);
                                   return r && r->tag_id == 3;
                                 }),
                  ds.events.end());
  EXPECT_EQ(ds.manifest.tags.size(), 2u);
  return ds;
}

// uwb-ekf on a robot with two tags (multitag_room without its third), started from the first
// epoch with no start pose: the heading is within a few degrees a second after its first
// estimate while the robot still stands, and the position beats the same filter on one tag;
// uwb-ekf on the primary tag alone has no heading until the robot moves.
TEST(UwbEkfMultitag, TwoTagsGiveTheHeadingWithinOneSecondWithoutMotion) {
  const data::Dataset ds = twoTagRoom();
  const auto h = headingWhileStanding(ds, "uwb-ekf:start=fix");
  const auto two = eval::evaluateMethod(ds, "uwb-ekf:start=fix", 1, 1);
  const auto one = eval::evaluateMethod(ds, "uwb-ekf:start=fix,tags=primary", 1, 1);
  std::printf(
      "[ HEADING  ] uwb-ekf, two tags, standing still, 1 s after its first estimate: mean "
      "|heading error| %.2f deg, worst %.2f deg over %ld estimates; whole run rmse_2d %.4f m, "
      "yaw rmse %.2f deg (primary tag alone: %.4f m)\n",
      h.mean_deg, h.worst_deg, h.n, two.metrics.rmse_2d, two.metrics.rmse_yaw_deg,
      one.metrics.rmse_2d);
  EXPECT_GT(h.n, 50);
  EXPECT_LT(h.mean_deg, 5.0);
  EXPECT_LT(h.worst_deg, 15.0);
  EXPECT_LT(two.metrics.rmse_2d, 0.6 * one.metrics.rmse_2d);
  EXPECT_LT(two.metrics.rmse_yaw_deg, 8.0);
  // Bad ranges among every tag's are rejected and counted; no estimate is ever non-finite.
  data::Dataset bad = ds;
  std::vector<loc::Event> events;
  long k = 0;
  for (const auto& e : ds.events) {
    events.push_back(e);
    if (const auto* r = std::get_if<uwb::Range>(&e); r && ++k % 37 == 0) {
      uwb::Range x = *r;
      x.range = (k / 37) % 3 == 0 ? std::numeric_limits<double>::quiet_NaN()
                                  : ((k / 37) % 3 == 1 ? -1.0 : x.range);
      if ((k / 37) % 3 == 2) x.anchor_id = 99;
      events.emplace_back(x);
    }
  }
  bad.events = events;
  const auto corrupted = eval::runMethod(bad, "uwb-ekf", 1);
  ASSERT_FALSE(corrupted.trajectory.empty());
  for (const auto& e : corrupted.trajectory)
    ASSERT_TRUE(e.pose.allFinite() && e.covariance.allFinite()) << e.t;
  EXPECT_EQ(corrupted.statistics.rejected.count("non_finite_estimate"), 0u);
  for (const char* reason : {"non_finite", "negative_range", "unknown_anchor"})
    EXPECT_GT(corrupted.statistics.rejected.count(reason), 0u) << reason;
  const auto primary = eval::runMethod(ds, "uwb-ekf:start=fix,tags=primary", 1);
  EXPECT_GT(primary.statistics.rejected.at("secondary_tag"), 0);
  for (const auto& e : primary.trajectory) {
    if (e.t < ds.start_time + 9.5) {
      EXPECT_FALSE(e.heading_valid) << e.t;
    }
  }
}

// Every range filter built on uwb-ekf reads both tags of the two-tag room, started from an epoch
// with no start pose: each has the heading within a few degrees a second after its first
// estimate while the robot stands, keeps it while it moves, and places the robot better than
// the same filter on its primary tag, which has no heading until the robot moves. The worst
// standing error is at one noisy stretch (6.7 s after the first estimate) for every filter:
// 9.7-10.7 deg for those with a fixed R, 13.6-16.3 deg for the adaptive ones, whose R follows
// the innovations down (uwb-shkf, uwb-iahckf, uwb-akf); each gets its own bound on it.
TEST(UwbEkfMultitag, EveryRangeFilterGetsTheHeadingFromTwoTags) {
  const data::Dataset ds = twoTagRoom();
  const std::vector<std::pair<std::string, double>> filters = {
      {"uwb-ckf", 15.0},      {"uwb-hinf-ckf", 15.0}, {"uwb-iahckf", 20.0},
      {"uwb-srukf", 15.0},    {"uwb-shkf", 20.0},     {"uwb-akf:mode=ranges", 20.0},
      {"federated-ekf", 15.0}};
  for (const auto& [method, worst_deg] : filters) {
    const std::string spec = method + (method.find(':') == std::string::npos ? ":" : ",");
    const auto h = headingWhileStanding(ds, spec + "start=fix");
    const auto two = eval::evaluateMethod(ds, spec + "start=fix", 1, 1);
    const auto one = eval::evaluateMethod(ds, spec + "start=fix,tags=primary", 1, 1);
    std::printf(
        "[ HEADING  ] %s, two tags, standing: mean |heading error| %.2f deg, worst %.2f deg "
        "(%.2f s after the first estimate) over %ld estimates; whole run rmse_2d %.4f m, yaw "
        "rmse %.2f deg (primary tag alone: %.4f m)\n",
        method.c_str(), h.mean_deg, h.worst_deg, h.worst_after, h.n, two.metrics.rmse_2d,
        two.metrics.rmse_yaw_deg, one.metrics.rmse_2d);
    EXPECT_GT(h.n, 50) << method;
    EXPECT_LT(h.mean_deg, 5.0) << method;
    EXPECT_LT(h.worst_deg, worst_deg) << method;
    EXPECT_LT(two.metrics.rmse_2d, 0.6 * one.metrics.rmse_2d) << method;
    EXPECT_LT(two.metrics.rmse_yaw_deg, 8.0) << method;
    const auto primary = eval::runMethod(ds, spec + "start=fix,tags=primary", 1);
    for (const auto& e : primary.trajectory) {
      if (e.t < ds.start_time + 9.5) {
        EXPECT_FALSE(e.heading_valid) << method << " " << e.t;
      }
    }
  }
}

// The per-epoch solvers (uwb-ls, uwb-gn, uwb-chan) and the filters on their fixes (uwb-kf,
// uwb-akf, uwb-iakf, uwb-ctrv-ekf) read both tags of the two-tag room: each tag multilaterated on
// its own against its own continuity track, and the lever arms fitted to the two points. The
// heading is known while the robot stands, and the robot is placed far better than from the
// primary tag alone, whose point gives no heading until the robot moves (the lever arm then
// swings about the tag with a heading from the noisy motion: 0.19 m for uwb-gn on the three-tag
// room against 0.03 m with every tag).
TEST(EpochTags, EverySolverAndFixFilterGetsThePoseFromTwoTags) {
  const data::Dataset ds = twoTagRoom();
  for (const std::string method :
       {"uwb-ls", "uwb-gn", "uwb-chan", "uwb-kf", "uwb-akf", "uwb-iakf", "uwb-ctrv-ekf"}) {
    const auto h = headingWhileStanding(ds, method);
    const auto two = eval::evaluateMethod(ds, method, 1, 1);
    const auto one = eval::evaluateMethod(ds, method + ":tags=primary", 1, 1);
    std::printf(
        "[ HEADING  ] %s, two tags, standing: mean |heading error| %.2f deg, worst %.2f deg over "
        "%ld estimates; whole run rmse_2d %.4f m, yaw rmse %.2f deg (primary tag alone: %.4f "
        "m)\n",
        method.c_str(), h.mean_deg, h.worst_deg, h.n, two.metrics.rmse_2d, two.metrics.rmse_yaw_deg,
        one.metrics.rmse_2d);
    EXPECT_GT(h.n, 50) << method;
    EXPECT_LT(h.mean_deg, 10.0) << method;
    EXPECT_LT(two.metrics.rmse_2d, 0.6 * one.metrics.rmse_2d) << method;
    // A per-epoch heading from two points 0.28 m apart, each to about 5 cm: some 14 degrees.
    EXPECT_LT(two.metrics.rmse_yaw_deg, method.find("kf") == std::string::npos ? 15.0 : 8.0)
        << method;
    EXPECT_GT(two.metrics.coverage, 0.99) << method;
    const auto primary = eval::runMethod(ds, method + ":tags=primary", 1);
    EXPECT_GT(primary.statistics.rejected.at("secondary_tag"), 0) << method;
  }
}

// A tag that disagrees with the others is left out, and the others place the robot: a tag whose
// ranges to one anchor read long (a reflection, 0.6 m for 30 s) fails its own fix's residual
// test; a tag whose lever arm is wrong (0.3 m, for 30 s) fits its ranges but not the others'
// rigid fit. With two tags there is no telling which is wrong (and a lever arm wrong across their
// baseline only turns the pair): the epoch falls back to the primary tag's own fix.
TEST(EpochTags, ATagThatDisagreesWithTheOthersIsLeftOut) {
  // `tag`'s ranges from 30 to 60 s changed by `change`.
  auto changed = [](data::Dataset ds, int tag, const std::function<void(uwb::Range&)>& change) {
    for (auto& e : ds.events)
      if (auto* r = std::get_if<uwb::Range>(&e);
          r && r->tag_id == tag && r->t > ds.start_time + 30.0 && r->t < ds.start_time + 60.0)
        change(*r);
    return ds;
  };
  auto reflected = [](uwb::Range& r) { r.range += r.anchor_id == 1 ? 0.6 : 0.0; };
  auto misplaced = [](uwb::Range& r) { r.tag_on_robot.x() += 0.3; };
  auto left_out = [](const eval::RunResult& run) {
    const auto it = run.statistics.rejected.find("tag_fix_left_out");
    return it == run.statistics.rejected.end() ? 0L : it->second;
  };
  const data::Dataset three = test::simulatedScenario("multitag_room", 1);
  const double clean = eval::evaluateMethod(three, "uwb-gn", 1, 1).metrics.rmse_2d;
  for (const auto& [what, change] :
       std::vector<std::pair<std::string, std::function<void(uwb::Range&)>>>{
           {"one anchor's ranges 0.6 m long", reflected}, {"its lever arm 0.3 m off", misplaced}}) {
    const data::Dataset bad = changed(three, 3, change);
    const auto summary = eval::evaluateMethod(bad, "uwb-gn", 1, 1);
    const auto run = eval::runMethod(bad, "uwb-gn", 1);
    std::printf(
        "[ TAGS     ] uwb-gn, three tags, tag 3 with %s for 30 s: rmse_2d %.4f m (clean %.4f), "
        "yaw rmse %.2f deg, %ld of its ranges left out\n",
        what.c_str(), summary.metrics.rmse_2d, clean, summary.metrics.rmse_yaw_deg, left_out(run));
    EXPECT_GT(left_out(run), 4L * 250) << what;  // of some 300 epochs
    EXPECT_LT(summary.metrics.rmse_2d, 1.2 * clean) << what;
  }
  // Along the two tags' baseline (0.28 -> 0.58 m apart): across it, the pair would only turn.
  const auto two = eval::runMethod(
      changed(twoTagRoom(), 2, [](uwb::Range& r) { r.tag_on_robot.y() += 0.3; }), "uwb-gn", 1);
  ASSERT_GT(two.statistics.events.count("tags_fix_inconsistent"), 0u);
  std::printf(
      "[ TAGS     ] two tags, tag 2's lever arm 0.3 m off for 30 s: %ld epochs without a fit\n",
      two.statistics.events.at("tags_fix_inconsistent"));
  EXPECT_GT(two.statistics.events.at("tags_fix_inconsistent"), 250);
  for (const auto& e : two.trajectory) ASSERT_TRUE(e.pose.allFinite()) << e.t;
}

// multitag_room ranging a round every 0.5 s, the anchors staggered over it: the tags together
// (each anchor's three ranges at one instant) or in turn (each tag its own third of the round).
data::Dataset slowRoundsRoom(bool in_turn) {
  auto s =
      data::loadScenario(std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/multitag_room.ini");
  s.uwb.rate = 2.0;
  s.uwb.synchronous = false;
  s.uwb.tags_in_turn = in_turn;
  const auto dir = test::scratchDir() / (in_turn ? "slow_rounds_in_turn" : "slow_rounds_together");
  return data::loadDataset(data::writeSimulation(s, 1, dir.string()), "");
}

// The per-epoch solvers and the fix filters on robots whose tags range together over a slow,
// staggered round, or in turn. The epoch window with several tags is the round's span (the gaps
// between ranges gave 0.15 s, which split each round into pieces no tag could be fixed from:
// no estimate at all with the tags together, 0.6 of the epochs with a heading in turn), and
// every tag's point is taken at the epoch's time, so the lever arms fit points of one instant.
// The gap rule on these data is what `window=0.15` gives: no estimate with the tags together;
// in turn, uwb-gn 0.109 m and uwb-kf 0.099 m, without a heading.
TEST(EpochTags, TagsThatRangeTogetherOrInTurnOverASlowRoundAreFixedTogether) {
  for (bool in_turn : {false, true}) {
    const data::Dataset ds = slowRoundsRoom(in_turn);
    std::set<double> stamps;
    for (const auto& e : ds.events)
      if (const auto* r = std::get_if<uwb::Range>(&e)) stamps.insert(r->t);
    // 240 rounds of 4 anchor instants, or of 12 (one per tag and anchor), and the first instant
    // of a 241st at 120 s.
    EXPECT_EQ(stamps.size(), (in_turn ? 12u : 4u) * 240u + 1u) << in_turn;
    for (const std::string method : {"uwb-gn", "uwb-kf"}) {
      const auto run = eval::evaluateMethod(ds, method, 1, 1);
      const auto h = headingWhileStanding(ds, method);
      std::printf(
          "[ ROUNDS   ] tags %s, a round every 0.5 s: %s coverage %.2f, rmse_2d %.4f m, yaw "
          "rmse %.2f deg; standing: mean |heading error| %.2f deg over %ld estimates\n",
          in_turn ? "in turn" : "together", method.c_str(), run.metrics.coverage,
          run.metrics.rmse_2d, run.metrics.rmse_yaw_deg, h.mean_deg, h.n);
      EXPECT_GT(run.metrics.coverage, 0.95) << method << in_turn;
      // Each tag's point at its own ranges' mean time instead: in turn, 0.039 / 0.048 m and
      // 12.3 / 15.2 degrees (uwb-gn / uwb-kf), against 0.033 / 0.031 m and 7.9 / 7.6.
      EXPECT_LT(run.metrics.rmse_2d, 0.04) << method << in_turn;
      EXPECT_LT(run.metrics.rmse_yaw_deg, 10.0) << method << in_turn;
      EXPECT_GT(h.n, 10) << method << in_turn;
      EXPECT_LT(h.mean_deg, 10.0) << method << in_turn;
    }
  }
}

// Two tags that range unlike each other: tag 2's ranges get 0.2 m more noise. One std learnt over
// both is mostly tag 0's, and uwb-pf's NLOS test rejects tag 2's good ranges at it; with a std per
// tag (tag_sigma=1, the default) tag 2 takes its own, learnt at the start.
TEST(UwbPfTags, ATagThatRangesWorseGetsItsOwnStd) {
  data::Dataset ds = twoTagRoom();
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 0.2);
  for (auto& e : ds.events)
    if (auto* r = std::get_if<uwb::Range>(&e); r && r->tag_id == 2) r->range += g(rng);
  const auto own = eval::runMethod(ds, "uwb-pf", 1);
  const auto one = eval::runMethod(ds, "uwb-pf:tag_sigma=0", 1);
  const auto own_m = eval::evaluateMethod(ds, "uwb-pf", 1, 1).metrics;
  const auto one_m = eval::evaluateMethod(ds, "uwb-pf:tag_sigma=0", 1, 1).metrics;
  auto rejected = [](const eval::RunResult& run) {
    const auto it = run.statistics.rejected.find("nlos_pose");
    return it == run.statistics.rejected.end() ? 0L : it->second;
  };
  const auto& tags = own.statistics.estimated_tag_noise;
  ASSERT_EQ(tags.size(), 2u);
  std::printf(
      "[ TAGS     ] uwb-pf, tag 2 with 0.2 m more noise: learnt std tag 0 %.3f, tag 2 %.3f m; "
      "rmse_2d %.4f m, %ld ranges failed the NLOS test (one std for both: %.4f m, %ld)\n",
      tags.at(0).sigma, tags.at(2).sigma, own_m.rmse_2d, rejected(own), one_m.rmse_2d,
      rejected(one));
  EXPECT_GT(tags.at(2).sigma, 2.5 * tags.at(0).sigma);
  EXPECT_EQ(own.statistics.events.at("tag_sigma_widened"), 1);
  EXPECT_EQ(one.statistics.events.count("tag_sigma_widened"), 0u);
  EXPECT_LT(rejected(own), rejected(one) / 2);
  EXPECT_LT(own_m.rmse_2d, one_m.rmse_2d);
  for (const auto& e : own.trajectory) ASSERT_TRUE(e.pose.allFinite()) << e.t;
}

// The point filters after the heading has gone unobserved: tag 2's ranges are dropped for 30 s
// while the robot drives and turns, so only tag 0's remain and the heading's std grows past
// what 2n points can span (sqrt(6) sigma beyond +-pi: they wrap round the circle and say
// nothing of the heading). Held at 60 deg (boundHeadingSpread), the heading is learnt again
// within seconds of tag 2's return; unbounded, uwb-ckf never learnt it again on the MRPT demo
// with simulated tags (2.93 m).
TEST(UwbEkfMultitag, PointFiltersLearnTheHeadingAgainAfterItWentUnobserved) {
  data::Dataset ds = twoTagRoom();
  const double from = ds.start_time + 20.0, to = ds.start_time + 50.0;
  ds.events.erase(std::remove_if(ds.events.begin(), ds.events.end(),
                                 [&](const loc::Event& e) {
                                   const auto* r = std::get_if<uwb::Range>(&e);
                                   return r && r->tag_id == 2 && r->t > from && r->t < to;
                                 }),
                  ds.events.end());
  for (const std::string method : {"uwb-ckf", "uwb-srukf", "uwb-ekf"}) {
    const auto run = eval::runMethod(ds, method + ":start=fix", 1);
    ASSERT_FALSE(run.trajectory.empty()) << method;
    double sum = 0.0;
    long n = 0, valid = 0;
    for (const auto& e : run.trajectory) {
      if (e.t < to + 3.0) continue;
      const auto truth = eval::interpolateGroundTruth(ds.ground_truth, e.t, 1.0);
      if (!truth) continue;
      ++n;
      if (!e.heading_valid) continue;
      ++valid;
      sum += std::abs(wrapAngle(e.pose.z() - truth->z())) * 180.0 / M_PI;
    }
    const auto events = run.statistics.events;
    const long bounded = events.count("heading_std_bounded") ? events.at("heading_std_bounded") : 0;
    std::printf(
        "[ HEADING  ] %s, 3 s after tag 2's 30 s outage on: heading valid on %ld of %ld "
        "estimates, mean |error| %.2f deg; heading std bounded %ld times\n",
        method.c_str(), valid, n, valid ? sum / static_cast<double>(valid) : -1.0, bounded);
    ASSERT_GT(n, 100) << method;
    EXPECT_GT(valid, 0.95 * static_cast<double>(n)) << method;
    EXPECT_LT(sum / static_cast<double>(std::max(valid, 1L)), 8.0) << method;
    if (method != "uwb-ekf") {
      EXPECT_GT(bounded, 0) << method;
    }
  }
}

// Anchors moved by 0.5 m and per-anchor biases of +-0.3 m: calibration against the reference
// recovers the anchors within 5 cm and the biases within 3 cm.
TEST(Calibration, RecoversPerturbedAnchorsAndBiases) {
  data::Dataset ds = test::simulatedScenario("multitag_room", 3);
  const std::map<int, double> bias = {{1, 0.3}, {2, -0.3}, {3, 0.25}, {4, -0.2}};
  for (auto& e : ds.events)
    if (auto* r = std::get_if<uwb::Range>(&e)) r->range += bias.at(r->anchor_id);
  const auto truth = ds.anchors;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI);
  for (auto& a : ds.anchors) {
    const double th = angle(rng);
    a.position.head<2>() += 0.5 * Eigen::Vector2d(std::cos(th), std::sin(th));
  }
  eval::CalibrationOptions o;
  o.per_link = false;
  for (const auto& a : ds.anchors) o.free_anchors.push_back(a.id);
  const auto result = eval::calibrateRanges({&ds}, o);
  for (const auto& a : truth) {
    const auto* got = uwb::findAnchor(result.anchors, a.id);
    ASSERT_NE(got, nullptr);
    const double err = (got->position - a.position).norm();
    std::printf("[ CALIB    ] anchor %d: position error %.4f m\n", a.id, err);
    EXPECT_LT(err, 0.05) << a.id;
  }
  for (const auto& b : result.biases) {
    std::printf("[ CALIB    ] anchor %d: bias %.4f m (true %.2f), sigma %.4f m\n", b.anchor_id,
                b.bias, bias.at(b.anchor_id), b.sigma);
    EXPECT_NEAR(b.bias, bias.at(b.anchor_id), 0.03) << b.anchor_id;
    EXPECT_NEAR(b.sigma, 0.05, 0.01) << b.anchor_id;
  }
}

TEST(Manifest, ReadsTheTagListAndTheBiasFile) {
  const auto dir = test::scratchDir();
  test::writeText(dir / "a.csv", "id,x,y,z\n1,0,0,1\n2,5,0,1\n");
  test::writeText(dir / "b.csv", "anchor_id,tag_id,bias\n1,0,0.25\n1,*,0.1\n2,*,-0.05,0.01\n");
  const auto m = data::loadManifest(
      test::writeText(dir / "m.ini",
                      "[dataset]\nrawlog = x.rawlog\n[anchors]\nanchors_csv = a.csv\nbias_csv = "
                      "b.csv\n[tag]\ntag_0 = 0.1 -0.2 1.0\ntag_4 = -0.3 0.2 1.1\n"),
      "");
  ASSERT_EQ(m.tags.size(), 2u);
  EXPECT_EQ(m.tags.at(4), Eigen::Vector3d(-0.3, 0.2, 1.1));
  ASSERT_EQ(m.biases.size(), 3u);
  EXPECT_DOUBLE_EQ(data::findBias(m.biases, 1, 0)->bias, 0.25);  // the tag's own row
  EXPECT_DOUBLE_EQ(data::findBias(m.biases, 1, 4)->bias, 0.1);   // the every-tag row
  EXPECT_DOUBLE_EQ(data::findBias(m.biases, 2, 0)->scale, 0.01);
  EXPECT_EQ(data::findBias(m.biases, 3, 0), nullptr);
  // Errors name the file and line.
  test::expectErrorMentions<data::InputError>(
      [&] {
        data::loadManifest(test::writeText(dir / "bad.ini",
                                           "[dataset]\nrawlog = x.rawlog\n[anchors]\nanchors_csv "
                                           "= a.csv\n[tag]\ntag_1 = 0.1 oops 1\n"),
                           "");
      },
      {"bad.ini:6", "tag_1", "x y z"});
  test::expectErrorMentions<data::InputError>(
      [&] { data::loadBiasCsv(test::writeText(dir / "bb.csv", "1,0,0.1\n1,0,0.2\n")); },
      {"bb.csv:2", "duplicate"});
  test::expectErrorMentions<data::InputError>(
      [&] { data::loadBiasCsv(test::writeText(dir / "bs.csv", "1,0,0.1,0.9\n")); },
      {"bs.csv:1", "scale"});
}

// Three tags ranging at the same instants are not a collapsed clock.
TEST(Dataset, SynchronousTagsAreNotCollapsedTime) {
  const data::Dataset ds = test::simulatedScenario("multitag_room", 2);
  EXPECT_FALSE(ds.collapsed_time);
  EXPECT_FALSE(data::collapsedTimeWarning(ds.events).has_value());
}

TEST(Lias, ParsesItsTimeFormat) {
  EXPECT_DOUBLE_EQ(*data::parseDateTime("1970-01-02 0:00:01.5"), 86401.5);
  EXPECT_NEAR(*data::parseDateTime("2022-08-15 9:42:24.766"), 1660556544.766, 1e-6);
  EXPECT_FALSE(data::parseDateTime("2022-13-15 9:42:24").has_value());
  EXPECT_FALSE(data::parseDateTime("9:42:24.766").has_value());
}

TEST(Lias, ACorruptFileNamesItsLine) {
  const auto dir = test::scratchDir();
  std::filesystem::create_directories(dir / "Planar_Dataset" / "Dynamic");
  std::filesystem::create_directories(dir / "Dynamic");
  std::string readme = "| Tag 0 | 0 | 0 | 0 |\n| Tag 1 | 0 | 0.2 | 0 |\n| Tag 2 | 0.2 | 0 | 0 |\n";
  for (int a = 0; a < 8; ++a)
    readme += "| Anchor " + std::to_string(a) + " | " + std::to_string(a) + " | 1 | 1 |\n";
  test::writeText(dir / "Planar_Dataset" / "Dynamic" / "README.md", readme);
  const auto uwb = test::writeText(dir / "Dynamic" / "UWB_dynamic_exp_x.csv",
                                   "2022-08-15 9:42:24.766,1,2\nnot a time,1\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importLias(uwb, (dir / "out").string()); },
      {"UWB_dynamic_exp_x.csv:2", "expected a time"});
  // An anchor number too long for an int (found by fuzzing: std::stoi threw out_of_range,
  // which no caller expects): an error naming the README's line.
  const auto bad_readme = test::writeText(dir / "Planar_Dataset" / "Dynamic" / "README.md",
                                          readme + "| Anchor 22222222222222222222 | 1 | 1 | 1 |\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importLias(uwb, (dir / "out").string()); },
      {bad_readme + ":12", "Anchor number", "integer id"});
  // Eight anchors, but numbered 1 to 8 (found by fuzzing: anchor 0 was then looked up and not
  // found): an error naming the README.
  std::string shifted = "| Tag 0 | 0 | 0 | 0 |\n| Tag 1 | 0 | 0.2 | 0 |\n| Tag 2 | 0.2 | 0 | 0 |\n";
  for (int a = 1; a <= 8; ++a)
    shifted += "| Anchor " + std::to_string(a) + " | " + std::to_string(a) + " | 1 | 1 |\n";
  test::writeText(dir / "Planar_Dataset" / "Dynamic" / "README.md", shifted);
  test::expectErrorMentions<data::InputError>(
      [&] { data::importLias(uwb, (dir / "out").string()); },
      {"README.md", "anchors numbered 0 to 7", "found 1 2 3 4 5 6 7 8"});
  // Without the README's tables: an error naming the README.
  test::writeText(dir / "Planar_Dataset" / "Dynamic" / "README.md", "# nothing here\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importLias(uwb, (dir / "out").string()); },
      {"README.md", "3 tags and 8 anchors"});
}

// A static run's heading is the README's yaw turned into the tags' frame: by --yaw-offset when
// given, else by the dynamic run's frame; with neither, the README's yaw, said to be unchecked.
TEST(Lias, AStaticRunsHeadingTakesTheMotionCapturesFrame) {
  const auto dir = test::scratchDir();
  std::filesystem::create_directories(dir / "Planar_Dataset" / "Static");
  std::filesystem::create_directories(dir / "Static");
  std::string readme =
      "### 2022/8/14\n| Tag 0 | 0 | -0.14 | 0 |\n| Tag 1 | 0 | 0.14 | 0 |\n"
      "| Tag 2 | 0.2 | 0.14 | 0 |\n";
  for (int a = 0; a < 8; ++a)
    readme += "| Anchor " + std::to_string(a) + " | " + std::to_string(a) + " | " +
              std::to_string(a % 3) + " | 1 |\n";
  readme += "| Pose 1 | 10.0 | 1.5 | -0.5 |\n|        | 70.0 | 1.4 | -0.4 |\n";
  test::writeText(dir / "Planar_Dataset" / "Static" / "README.md", readme);
  std::string rows;
  for (int i = 0; i < 5; ++i) {
    rows += "2022-08-14 11:43:1" + std::to_string(i) + ".000";
    for (int k = 0; k < 24; ++k) rows += ",3.00";
    rows += "\n";
  }
  const auto uwb = test::writeText(dir / "Static" / "UWB_static_exp_8_14_pos1_deg_0.csv", rows);
  auto headingOf = [](const std::string& manifest) {
    const auto ds = data::loadDataset(manifest, "");
    return ds.ground_truth.front().pose.z() * 180.0 / M_PI;
  };
  data::LiasImportParams p;
  p.tag_height = 1.0;
  const auto unchecked = data::importLias(uwb, (dir / "a").string(), p);
  EXPECT_NEAR(headingOf(unchecked.manifest), 10.0, 1e-5);  // the TUM quaternion's digits
  bool said = false;
  for (const auto& n : unchecked.notes) said |= n.find("unchecked") != std::string::npos;
  EXPECT_TRUE(said);
  p.yaw_offset_deg = 6.0;
  const auto given = data::importLias(uwb, (dir / "b").string(), p);
  EXPECT_NEAR(headingOf(given.manifest), 16.0, 1e-5);
  // A motion capture beside without its run's ranges gives the height, not the frame.
  std::filesystem::create_directories(dir / "Dynamic");
  test::writeText(
      dir / "Dynamic" / "motion_capture_dynamic_exp_x.csv",
      "time,x,y,z,rotation,,,\n2022-08-15 9:42:22.968,0,0,0.9,1,0,0,0\n"
      "2022-08-15 9:42:22.978,0,0,0.9,1,0,0,0\n2022-08-15 9:42:22.988,0,0,0.9,1,0,0,0\n");
  const auto beside = data::importLias(uwb, (dir / "c").string());
  EXPECT_NEAR(headingOf(beside.manifest), 10.0, 1e-5);
  const auto ds = data::loadDataset(beside.manifest, "");
  EXPECT_NEAR(ds.manifest.tags.at(0).z(), 0.9, 1e-9);
  said = false;
  for (const auto& n : beside.notes)
    said |= n.find("unchecked: no dynamic run's ranges") != std::string::npos;
  EXPECT_TRUE(said);  // With its ranges too, but a dynamic README short of anchors (found by
                      // fuzzing: the frame's
  // search then read a missing anchor): the static import still works, its heading unchecked.
  std::filesystem::create_directories(dir / "Planar_Dataset" / "Dynamic");
  test::writeText(
      dir / "Planar_Dataset" / "Dynamic" / "README.md",
      "| Tag 0 | 0 | -0.14 | 0 |\n| Tag 1 | 0 | 0.14 | 0 |\n| Tag 2 | 0.2 | 0.14 | 0 |\n"
      "| Anchor 0 | 0 | 0 | 1 |\n");
  test::writeText(dir / "Dynamic" / "UWB_dynamic_exp_x.csv", rows);
  const auto short_readme = data::importLias(uwb, (dir / "d").string());
  EXPECT_NEAR(headingOf(short_readme.manifest), 10.0, 1e-5);
  said = false;
  for (const auto& n : short_readme.notes)
    said |= n.find("unchecked: the dynamic run beside could not be read") != std::string::npos &&
            n.find("3 tags and 8 anchors") != std::string::npos;
  EXPECT_TRUE(said);
}

// The shared recordings: biases calibrated on the three static runs at known poses, applied to
// the fast dynamic run. Measured: 4.4 cm position RMSE and 6.3 deg heading RMSE (the heading
// misses the 3 deg goal: see the README's multi-tag section). The thresholds guard those.
TEST(Lias, StaticCalibrationCarriesToTheFastDynamicRun) {
  const auto root = test::sharedData("lias_cuhksz_planar_uwb");
  UWBLOC_REQUIRE_SHARED_DATA(root);
  const auto dir = test::scratchDir();
  std::vector<data::Dataset> statics;
  for (int p = 1; p <= 3; ++p) {
    const auto out = dir / ("pos" + std::to_string(p));
    const auto s = data::importLias(
        (root / "Static" / ("UWB_static_exp_8_14_pos" + std::to_string(p) + "_deg_0.csv")).string(),
        out.string());
    EXPECT_GT(s.skipped.at("uwb_row_short"), 0);  // rows short of an anchor are counted
    statics.push_back(data::loadDataset(s.manifest, ""));
  }
  // Their heading is the README's yaw in the frame found on the dynamic run beside them (+6
  // degrees): each static epoch's three-tag heading, uncalibrated, then agrees within a few
  // degrees (medians 7.2, 2.0 and 2.4; 13.2, 8.0 and 3.6 with the README's yaw taken as it is).
  double median_sum = 0.0;
  for (const auto& d : statics) {
    EXPECT_NEAR(d.ground_truth.front().pose.z() * 180.0 / M_PI, 6.0, 1.5);
    const auto one = eval::evaluateMethod(d, "uwb-multitag:smooth=false", 1, 1);
    std::printf("[ LIAS     ] static run, no calibration: median |heading error| %.2f deg\n",
                one.metrics.median_yaw_deg);
    median_sum += one.metrics.median_yaw_deg;
  }
  EXPECT_LT(median_sum / 3.0, 5.0);
  std::vector<const data::Dataset*> in;
  for (const auto& d : statics) in.push_back(&d);
  const auto cal = eval::calibrateRanges(in, {});
  ASSERT_EQ(cal.biases.size(), 24u);
  data::writeFileAtomic((dir / "bias.csv").string(), data::formatBiasCsv(cal.biases));

  data::LiasImportParams params;
  params.bias_csv = (dir / "bias.csv").string();
  const auto s = data::importLias((root / "Dynamic" / "UWB_dynamic_exp_fast.csv").string(),
                                  (dir / "fast").string(), params);
  bool chosen = false;
  for (const auto& n : s.notes)
    chosen |= n.find("Chosen: heading +1 x the motion capture's yaw") != std::string::npos &&
              n.find("lever arm y taken as given") != std::string::npos;
  EXPECT_TRUE(chosen);
  const data::Dataset fast = data::loadDataset(s.manifest, "");
  EXPECT_EQ(fast.counts.at("ranges_bias_corrected"), s.ranges);
  const auto summary = eval::evaluateMethod(fast, "uwb-multitag", 1, 1);
  std::printf(
      "[ LIAS     ] fast run, static calibration: rmse_2d %.4f m, median %.4f, p95 %.4f; "
      "yaw rmse %.2f deg, median %.2f, p95 %.2f\n",
      summary.metrics.rmse_2d, summary.metrics.median_2d, summary.metrics.p95_2d,
      summary.metrics.rmse_yaw_deg, summary.metrics.median_yaw_deg, summary.metrics.p95_yaw_deg);
  EXPECT_LT(summary.metrics.rmse_2d, 0.05);
  EXPECT_LT(summary.metrics.rmse_yaw_deg, 7.5);
  // uwb-ekf reads all three tags too: as close, and far closer than on tag 0 alone.
  const auto ekf = eval::evaluateMethod(fast, "uwb-ekf", 1, 1);
  const auto ekf_one = eval::evaluateMethod(fast, "uwb-ekf:tags=primary", 1, 1);
  std::printf(
      "[ LIAS     ] fast run, static calibration: uwb-ekf rmse_2d %.4f m, yaw rmse %.2f deg; "
      "on tag 0 alone %.4f m\n",
      ekf.metrics.rmse_2d, ekf.metrics.rmse_yaw_deg, ekf_one.metrics.rmse_2d);
  EXPECT_LT(ekf.metrics.rmse_2d, 0.05);
  EXPECT_LT(ekf.metrics.rmse_yaw_deg, 7.5);
  EXPECT_LT(ekf.metrics.rmse_2d, 0.6 * ekf_one.metrics.rmse_2d);
  // So do the per-epoch solver and the filter on its fixes: each tag multilaterated on its own,
  // the lever arms fitted to the points (0.235 and 0.106 m on tag 0 alone).
  for (const std::string method : {"uwb-gn", "uwb-kf"}) {
    const auto all = eval::evaluateMethod(fast, method, 1, 1);
    const auto one = eval::evaluateMethod(fast, method + ":tags=primary", 1, 1);
    std::printf(
        "[ LIAS     ] fast run, static calibration: %s rmse_2d %.4f m, yaw rmse %.2f deg; on "
        "tag 0 alone %.4f m\n",
        method.c_str(), all.metrics.rmse_2d, all.metrics.rmse_yaw_deg, one.metrics.rmse_2d);
    EXPECT_LT(all.metrics.rmse_2d, 0.05) << method;
    EXPECT_LT(all.metrics.rmse_yaw_deg, 7.5) << method;
    EXPECT_LT(all.metrics.rmse_2d, 0.6 * one.metrics.rmse_2d) << method;
  }
}

}  // namespace
}  // namespace uwbloc

namespace uwbloc {
namespace {

// A node that stands still becomes an anchor where it stands; one that moves at 1 m/s does not.
TEST(MobileNode, StillNodeIsAnAnchorAMovingOneIsNot) {
  const std::vector<uwb::Anchor> fixed = {
      {1, {0, 0, 1.2}}, {2, {0, 8.28, 1.2}}, {3, {1.6, 8.28, 1.2}}};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  for (double speed : {0.0, 1.0}) {
    loc::MobileAnchors mobile(20, std::nullopt, 0.1);
    double t = 0.0;
    for (int k = 0; k < 100; ++k, t += 0.05) {
      const Eigen::Vector3d node(1.5, 2.0 + speed * t, 0.8);
      for (const auto& a : fixed) {
        uwb::Range r;
        r.t = t;
        r.tag_id = 1;
        r.on_robot = false;
        r.anchor_id = a.id;
        r.tag_on_robot = Eigen::Vector3d(0, 0, 0.8);
        r.range = (a.position - node).norm() + noise(rng);
        mobile.add(r, fixed);
      }
    }
    const auto anchor = mobile.anchor(uwb::kMobileAnchorBase + 1, t);
    if (speed == 0.0) {
      ASSERT_TRUE(anchor.has_value());
      EXPECT_LT((anchor->position.head<2>() - Eigen::Vector2d(1.5, 2.0)).norm(), 0.1);
      EXPECT_DOUBLE_EQ(anchor->position.z(), 0.8);
      EXPECT_FALSE(mobile.anchor(uwb::kMobileAnchorBase + 1, t + 3.0).has_value());  // stale
      // Its position is known to the fixes' scatter (0.1 m ranges: about 0.15 m here, the three
      // anchors nearly on a line).
      const double var = mobile.positionVariance(uwb::kMobileAnchorBase + 1);
      std::printf("[ MOBILE   ] still node's position std %.3f m\n", std::sqrt(var));
      EXPECT_GT(var, 0.01 * 0.01);
      EXPECT_LT(var, 0.2 * 0.2);
      EXPECT_EQ(mobile.positionVariance(uwb::kMobileAnchorBase + 2), 0.0);
    } else {
      EXPECT_FALSE(anchor.has_value());
    }
  }
}

// The mobile-node paper's corridor (3 anchors, a person's tag, a slow cart that stops): the
// cart as a temporary anchor lowers the error of least squares and of the CTRV EKF on the
// paper's least-squares fixes (solver=ls) and on its default Gauss-Newton ones. The ranges to the
// cart carry its position's scatter in their variance (positionVariance); without it the cart
// raised the Gauss-Newton filter's error, 0.174 -> 0.289 m.
TEST(MobileNode, TheCartHelpsInTheCorridor) {
  const data::Dataset ds = test::simulatedScenario("corridor", 1);
  for (const char* m : {"uwb-ls", "uwb-chan", "uwb-ctrv-ekf:solver=ls", "uwb-ctrv-ekf"}) {
    const auto with = eval::evaluateMethod(ds, m, 1, 1);
    const auto without = eval::evaluateMethod(
        ds, std::string(m) + (std::strchr(m, ':') ? "," : ":") + "mobile=false", 1, 1);
    std::printf("[ MOBILE   ] %-13s rmse %.3f m with the cart, %.3f m without; max %.3f / %.3f\n",
                m, with.metrics.rmse_2d, without.metrics.rmse_2d, with.metrics.max_2d,
                without.metrics.max_2d);
    EXPECT_LT(with.metrics.rmse_2d, 0.9 * without.metrics.rmse_2d) << m;
    EXPECT_EQ(without.rejected.count("mobile_anchor_moving"), 0u) << m;
  }
}

}  // namespace
}  // namespace uwbloc

namespace uwbloc {
namespace {

// Static ranging at known distances, in the Hanyang static layout: the error's offset and scale
// per condition and group are recovered; an empty file and corrupt rows are reported, not fatal.
TEST(Calibration, StaticRangingFitsOffsetAndScale) {
  const auto dir = test::scratchDir();
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0.0, 0.05);
  const std::string header = "timestamp,Distance,poll_tx_ts,poll_rx_ts,resp_tx_ts,resp_rx_ts\n";
  for (const auto& [cond, offset, scale] :
       {std::tuple{"LOS", 0.05, 0.004}, std::tuple{"NLOS", 0.20, 0.003}}) {
    const auto group = dir / cond / "height_100.0cm";
    std::filesystem::create_directories(group);
    for (int d = 2; d <= 40; d += 2) {
      std::string text = header;
      for (int k = 0; k < 50; ++k)
        text += "1.0," + std::to_string(d * (1.0 + scale) + offset + noise(rng)) + ",1,2,3,4\n";
      text += "1.0,,1,2,3,4\n";  // a corrupt row
      test::writeText(group / (std::to_string(d) + "m.csv"), text);
    }
    test::writeText(group / "42m.csv", "");  // an empty file
  }
  const auto report = eval::fitStaticRanging(dir.string());
  ASSERT_EQ(report.fits.size(), 2u);
  for (const auto& f : report.fits) {
    const bool los = f.condition == "LOS";
    EXPECT_EQ(f.files, 20);
    EXPECT_EQ(f.ranges, 1000);
    EXPECT_NEAR(f.offset, los ? 0.05 : 0.20, 0.01) << f.condition;
    EXPECT_NEAR(f.scale, los ? 0.004 : 0.003, 0.0005) << f.condition;
    EXPECT_NEAR(f.sigma, 0.05, 0.006) << f.condition;
  }
  const std::string text = eval::formatStaticRanging(report);
  EXPECT_NE(text.find("42m.csv: no range (empty file)"), std::string::npos) << text;
  EXPECT_NE(text.find("20 rows with an empty or corrupt field skipped, in 20 files"),
            std::string::npos)
      << text;
}

}  // namespace
}  // namespace uwbloc
