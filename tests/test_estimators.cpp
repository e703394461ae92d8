// Every registered method through one suite: coverage and an RMSE bound on a simulated room
// with every sensor, bad measurements rejected and counted, no NaN from the method itself, the
// guard that would drop one, and the registry's errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "kidnap.hpp"
#include "simulated_scenario.hpp"
#include "synthetic.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/methods/point_filters.hpp"
#include "uwbloc/localization/methods/uwb_shkf.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/localization/registry.hpp"
#include "uwbloc/uwb/range_model.hpp"

using namespace uwbloc;

namespace {

// The simulated PF-IBAS room (seed 1): UWB with NLOS, a LiDAR, odometry, an IMU and a map, so that
// every registered method has what it needs. One dataset for the whole binary.
const data::Dataset& room() {
  static const data::Dataset ds = test::simulatedScenario("pfibas_room", 1);
  return ds;
}

// 2D RMSE bound of each method on the room with filter seed 1, about 1.5 times what it scores
// (measured: `uwbloc compare -d <room>/dataset.ini --methods all`). A newly registered method
// fails here until it states its bound.
const std::map<std::string, double> kRoomBound = {{"uwb-ls", 0.70},
                                                  {"uwb-gn", 0.60},
                                                  {"uwb-chan", 0.60},
                                                  {"uwb-kf", 0.33},
                                                  {"uwb-akf", 0.57},
                                                  {"uwb-iakf", 0.72},
                                                  {"uwb-ctrv-ekf", 0.41},
                                                  {"uwb-ekf", 0.25},
                                                  {"uwb-ckf", 0.29},
                                                  {"uwb-hinf-ckf", 0.29},
                                                  {"uwb-iahckf", 0.29},
                                                  {"uwb-srukf", 0.29},
                                                  {"federated-ekf", 0.30},
                                                  {"uwb-shkf", 0.29},
                                                  {"uwb-ins", 0.28},
                                                  {"uwb-ins-ckf", 0.28},
                                                  {"uwb-ins-ickf", 0.28},
                                                  {"odom", 0.05},
                                                  {"lidar-icp", 0.17},
                                                  {"lidar-mcl", 0.03},
                                                  {"fused-naive", 0.04},
                                                  {"fused-pf", 0.03},
                                                  {"pf-sir", 0.03},
                                                  {"pf-ibas", 0.04},
                                                  {"pf-ibas-stratified", 0.04},
                                                  {"uwb-pf", 0.15},
                                                  {"graph-uwb-odom", 0.05},
                                                  {"graph-uwb", 0.26},
                                                  {"pf-ibas+graph", 0.045},
                                                  {"uwb-multitag", 0.33}};

std::string testName(const ::testing::TestParamInfo<std::string>& info) {
  std::string n = info.param;
  for (auto& ch : n)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return n;
}

// The stream with bad measurements mixed in: NaN, zero, negative and absurd ranges, an unknown
// anchor, time going back, NaN odometry and NaN IMU samples.
std::vector<loc::Event> corrupted(const std::vector<loc::Event>& events) {
  std::vector<loc::Event> bad;
  int i = 0, j = 0, k = 0;
  for (const auto& e : events) {
    bad.push_back(e);
    if (const auto* r = std::get_if<uwb::Range>(&e); r && ++i % 10 == 0) {
      uwb::Range x = *r;
      const int kind = (i / 10) % 6;
      if (kind == 0) x.range = std::numeric_limits<double>::quiet_NaN();
      if (kind == 1) x.range = 0.0;
      if (kind == 2) x.range = -2.0;
      if (kind == 3) x.range = 1e6;
      if (kind == 4) x.anchor_id = 99;
      if (kind == 5) x.t -= 5.0;
      bad.emplace_back(x);
    }
    if (const auto* m = std::get_if<loc::ImuSample>(&e); m && ++k % 50 == 0) {
      loc::ImuSample x = *m;
      x.accel.y() = std::numeric_limits<double>::quiet_NaN();
      bad.emplace_back(x);
    }
    if (const auto* o = std::get_if<loc::OdometryIncrement>(&e); o && ++j % 50 == 0) {
      loc::OdometryIncrement x = *o;
      x.delta.x() = std::numeric_limits<double>::quiet_NaN();
      bad.emplace_back(x);
    }
  }
  return bad;
}

bool needs(const std::string& method, const char* what) {
  const auto& n = loc::Registry::builtin().find(method)->needs;
  return std::find(n.begin(), n.end(), what) != n.end();
}

}  // namespace

class EveryMethod : public ::testing::TestWithParam<std::string> {};

// Coverage, an RMSE bound, and no non-finite estimate from the method itself: the guard in
// Estimator::process() (which drops one and counts it as non_finite_estimate) never fired.
TEST_P(EveryMethod, MeetsItsBoundOnTheRoom) {
  const std::string m = GetParam();
  const auto bound = kRoomBound.find(m);
  ASSERT_NE(bound, kRoomBound.end()) << m << " has no RMSE bound in kRoomBound";
  const auto run = eval::runMethod(room(), m, 1);
  const auto errors = eval::associate(run.trajectory, room().ground_truth);
  const auto metrics = eval::computeMetrics(errors, run.trajectory, room().ground_truth);
  std::printf("[ ROOM     ] %-20s rmse_2d %.4f m (bound %.3f), coverage %.3f\n", m.c_str(),
              metrics.rmse_2d, bound->second, metrics.coverage);
  EXPECT_GE(metrics.coverage, 0.9) << m;
  EXPECT_LT(metrics.rmse_2d, bound->second) << m;
  EXPECT_EQ(run.statistics.rejected.count("non_finite_estimate"), 0u) << m;
}

TEST_P(EveryMethod, RejectsBadMeasurementsAndNeverEmitsNaN) {
  const std::string m = GetParam();
  data::Dataset ds = room();
  ds.events = corrupted(ds.events);
  const auto run = eval::runMethod(ds, m, 5);
  for (const auto& p : run.trajectory) {
    ASSERT_TRUE(p.pose.allFinite()) << m << " at t=" << p.t;
    ASSERT_TRUE(p.covariance.allFinite()) << m << " at t=" << p.t;
  }
  EXPECT_EQ(run.statistics.rejected.count("non_finite_estimate"), 0u) << m;
  const auto& rej = run.statistics.rejected;
  if (needs(m, "ranges")) {
    for (const char* reason : {"non_finite", "zero_range", "negative_range", "beyond_max_range",
                               "unknown_anchor", "time_backwards"}) {
      EXPECT_GT(rej.count(reason), 0u) << m << " did not count " << reason;
    }
  }
  if (needs(m, "imu")) {
    EXPECT_GT(rej.count("non_finite_imu"), 0u) << m;
  }
  if (needs(m, "odometry") && m != "lidar-icp" && m != "graph-uwb-odom") {
    EXPECT_GT(rej.count("non_finite_odometry"), 0u) << m;
  }
  const auto errors = eval::associate(run.trajectory, ds.ground_truth);
  EXPECT_LT(eval::computeMetrics(errors, run.trajectory, ds.ground_truth).rmse_2d,
            kRoomBound.at(m) * 1.5)
      << m;
}

INSTANTIATE_TEST_SUITE_P(Registry, EveryMethod,
                         ::testing::ValuesIn(loc::Registry::builtin().names()), testName);

// Uwb-only methods on the synthetic square loop (exact odometry, four anchors, no LiDAR).
// The median the methods and the data checks share: the upper one of an even count, 0 when
// empty, and NaNs left out (std::nth_element given one may read past the range).
TEST(MedianOf, UpperMedianWithoutTheNaNs) {
  EXPECT_EQ(loc::medianOf({}), 0.0);
  EXPECT_EQ(loc::medianOf({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(loc::medianOf({4.0, 1.0, 3.0, 2.0}), 3.0);
  EXPECT_EQ(loc::medianOf({NAN, 5.0, NAN, 1.0, NAN, 3.0, NAN}), 3.0);
  EXPECT_EQ(loc::medianOf({NAN, NAN}), 0.0);
  EXPECT_EQ(loc::medianOf({HUGE_VAL, 1.0, 2.0}), 2.0);
}

TEST(SyntheticLoop, UwbMethodsConverge) {
  const data::Dataset ds = test::makeSquareLoop(3);
  for (const auto& [m, bound] :
       std::vector<std::pair<std::string, double>>{{"uwb-ls", 0.15},
                                                   {"uwb-gn", 0.15},
                                                   {"uwb-chan", 0.15},
                                                   {"uwb-kf", 0.12},
                                                   {"uwb-ekf", 0.10},
                                                   {"odom", 1e-6},
                                                   {"graph-uwb-odom", 0.05}}) {
    const auto run = eval::runMethod(ds, m, 3);
    const auto errors = eval::associate(run.trajectory, ds.ground_truth);
    const auto metrics = eval::computeMetrics(errors, run.trajectory, ds.ground_truth);
    EXPECT_GT(metrics.coverage, 0.95) << m;
    EXPECT_LT(metrics.rmse_2d, bound) << m;
  }
}

namespace {
/// Anchors 1 (0, 0), 2 (8, 0) and 3 (4, 7) at 1 m; the tag at 1 m, at `at(t)` over [0, duration]
/// (the reference at 10 Hz); each anchor's range 10 times a second (anchor k 0.02 k s after the
/// tick), the distance from `from(t, anchor id)` (default: the tag's place) plus 5 cm noise,
/// nothing when that gives no place.
data::Dataset threeAnchorWalk(
    const char* name, double duration, uint64_t seed,
    const std::function<Eigen::Vector2d(double)>& at,
    const std::function<std::optional<Eigen::Vector2d>(double, int)>& from = nullptr) {
  data::Dataset ds;
  ds.name = name;
  ds.anchors = {{1, {0, 0, 1.0}}, {2, {8, 0, 1.0}}, {3, {4, 7, 1.0}}};
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05);
  for (int k = 0; k * 0.1 <= duration; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector2d tag = at(t);
    ds.ground_truth.push_back({t, Eigen::Vector3d(tag.x(), tag.y(), 0.0)});
    for (size_t a = 0; a < ds.anchors.size(); ++a) {
      const auto p = from ? from(t, ds.anchors[a].id) : std::optional<Eigen::Vector2d>(tag);
      if (!p) continue;
      uwb::Range r;
      r.t = t + 0.02 * static_cast<double>(a);
      r.anchor_id = ds.anchors[a].id;
      r.range = (Eigen::Vector3d(p->x(), p->y(), 1.0) - ds.anchors[a].position).norm() + noise(rng);
      r.tag_on_robot = Eigen::Vector3d(0.0, 0.0, 1.0);
      ds.events.emplace_back(r);
    }
  }
  ds.start_time = 0.0;
  ds.end_time = duration + 0.06;
  return ds;
}
}  // namespace

// A tag still at P for 20 s, then at Q, which is as far from anchor 2 as P is (ranges at 10 Hz,
// 5 cm noise): a filter at P finds anchor 2 agreeing and anchors 1 and 3 off by 2 and 3 m. It
// uses anchor 2 every third range, so "12 unused ranges in a row" never says it is lost, and the
// quarantine never lets the others back (their innovations stay beyond readmit_tol). Using one
// anchor while refusing the others beyond readmission over max_gated ranges
// (lost_on_one_anchor) re-initialises it from a fix, at Q: within 0.2 m (held 5 s) after 1.2 s,
// against 7.1 s (uwb-ekf) and 9.4 s (uwb-ckf), once their predicted std outgrew reinit_std, and
// never (uwb-shkf) without it. On the MRPT demo uwb-shkf ran 4 m along beacon 2's circle for
// 5 s (0.572 -> 0.379 m) and federated-ekf 9 m for 10 s (1.383 -> 1.069 m).
TEST(RangeFilters, ReInitialiseWhenOneAnchorAloneStillAgrees) {
  const Eigen::Vector2d p(4, 3), q(3, 0);  // |P - A2| = |Q - A2| = 5 m
  const double t_move = 20.0;
  const data::Dataset ds =
      threeAnchorWalk("one_anchor_agrees", 60.0, 3, [&](double t) { return t < t_move ? p : q; });
  for (const std::string m : {"uwb-ekf", "uwb-ckf", "uwb-shkf", "uwb-iahckf"}) {
    const auto run = eval::runMethod(ds, m + ":sigma=0.05,calib=0", 1);
    const auto back = test::recoveryTime(ds, run.trajectory, t_move, 0.2, 5.0);
    std::printf("[ ONE-ANCH ] %-10s within 0.2 m of Q after %.1f s\n", m.c_str(),
                back.value_or(-1.0));
    EXPECT_GE(run.statistics.events.count("lost_on_one_anchor"), 1u) << m;
    ASSERT_TRUE(back.has_value()) << m << " never came back";
    EXPECT_LT(*back, 2.0) << m;
  }
}

namespace {
// The tag of threeAnchorWalk walks from (4, 3) towards the line AB (anchors 1 and 2) at 0.5 m/s,
// turns back on it at t_turn and walks back to (4, 3), while C's (anchor 3's) ranges are
// missing from 8 s to 20 s.
data::Dataset bounceOffTheLine(double t_turn) {
  const double v = 0.5, t_go = 10.0;
  const auto path = [=](double t) {
    const double walked = std::clamp(t - t_go, 0.0, 2.0 * (t_turn - t_go));
    return Eigen::Vector2d(4.0, 3.0 - v * std::min(walked, 2.0 * (t_turn - t_go) - walked));
  };
  return threeAnchorWalk("bounce_off_ab", 50.0, 5, path,
                         [=](double t, int anchor) -> std::optional<Eigen::Vector2d> {
                           if (anchor == 3 && t >= 8.0 && t < 20.0) return std::nullopt;
                           return path(t);
                         });
}
}  // namespace

// Two anchors fix a position up to its mirror image across their line. The tag of
// bounceOffTheLine walks onto the line AB and back (at 0.5 m/s, turning at 15.9 s, 5 cm short of
// the line) while C's ranges are missing: A's and B's ranges fit the walk on
// across the line as well as the walk back, and the constant-velocity filters walk on, to the
// mirror side. When C's ranges come back true at 20 s they are 5 m shorter than predicted,
// refused for good: without the rule the filters stay on the mirror side to the end (all four
// 6.0 m off at 50 s). The rule (mirrored_across_two_anchors) reflects them across AB after
// three such ranges: within 0.2 m (held 5 s) of the truth 0.2 s after C comes back.
// (federated-ekf's local filters, blind across the fold of AB by default, are back within 0.2 m
// 0.5 s after C without the rule; the rule is tested on them with fold_blind=0.)
TEST(RangeFilters, CrossBackWhenTheThirdAnchorSaysTheMirror) {
  const data::Dataset ds = bounceOffTheLine(15.9);
  for (const std::string m : {"uwb-ekf:", "uwb-ckf:", "uwb-shkf:", "federated-ekf:fold_blind=0,"}) {
    const auto run = eval::runMethod(ds, m + "sigma=0.05,calib=0", 1);
    const auto back = test::recoveryTime(ds, run.trajectory, 20.0, 0.2, 5.0);
    ASSERT_GT(run.trajectory.size(), 10u) << m;
    const auto& last = run.trajectory[run.trajectory.size() - 10];  // within the reference
    const auto gt = eval::interpolateGroundTruth(ds.ground_truth, last.t, 1.0);
    ASSERT_TRUE(gt.has_value()) << m;
    std::printf(
        "[ MIRROR   ] %-13s within 0.2 m after %.1f s (mirrored %zu times), %.2f m off at %.0f s\n",
        m.c_str(), back.value_or(-1.0), run.statistics.events.count("mirrored_across_two_anchors"),
        (last.pose.head<2>() - gt->head<2>()).norm(), last.t);
    EXPECT_GE(run.statistics.events.count("mirrored_across_two_anchors"), 1u) << m;
    ASSERT_TRUE(back.has_value()) << m << " never came back";
    EXPECT_LT(*back, 2.0) << m;
  }
}

// What the rule must leave alone: ranges of C that read what the mirror of the tag's place
// would give, for 10 s (15-25 s), the tag standing still.
// (a) At (4, 0.6), on C's side of AB and 0.6 m from it: C's ranges read 1.2 m long, as NLOS
//     reads, and the filter's position std across AB (A and B alone) reaches 0.24 m, so the line
//     is within its 3 sigma. Long ranges never pull a filter across: the reflection across a
//     line on C's far side is farther from C.
// (b) At (4, -3), across AB from C: C's ranges read 6 m short. The filter has not come near the
//     line since C was last used, so nothing can have put it on the wrong side. (The MRPT demo's
//     beacon 1 read its mirror's distance three ranges in a row at 73 s and 294 s, and every
//     range filter jumped 6-10 m before the rule asked for the line.)
TEST(RangeFilters, TheMirrorRuleLeavesLongRangesAndFarLinesAlone) {
  for (const Eigen::Vector2d& at : {Eigen::Vector2d(4.0, 0.6), Eigen::Vector2d(4.0, -3.0)}) {
    const Eigen::Vector2d mirror(at.x(), -at.y());
    const data::Dataset ds = threeAnchorWalk(
        "mirror_shaped_outliers", 40.0, 7, [&](double) { return at; },
        [&](double t, int anchor) -> std::optional<Eigen::Vector2d> {
          return anchor == 3 && t >= 15.0 && t < 25.0 ? mirror : at;
        });
    for (const std::string m : {"uwb-ekf", "uwb-ckf", "uwb-shkf", "federated-ekf"}) {
      const auto run = eval::runMethod(ds, m + ":sigma=0.05,calib=0", 1);
      const auto errors = eval::associate(run.trajectory, ds.ground_truth);
      const auto metrics = eval::computeMetrics(errors, run.trajectory, ds.ground_truth);
      std::printf("[ MIRROR   ] %-13s at (%.1f, %.1f): rmse_2d %.3f m, mirrored %zu times\n",
                  m.c_str(), at.x(), at.y(), metrics.rmse_2d,
                  run.statistics.events.count("mirrored_across_two_anchors"));
      EXPECT_EQ(run.statistics.events.count("mirrored_across_two_anchors"), 0u) << m;
      EXPECT_LT(metrics.rmse_2d, 0.2) << m;
    }
  }
}

// sigma=auto: the graph's variance-component estimate finds the simulated range noise, and
// bias=auto stays off without a bias.
TEST(SyntheticLoop, GraphEstimatesTheRangeNoise) {
  for (double sigma : {0.05, 0.3}) {
    const data::Dataset ds = test::makeSquareLoop(7, sigma, 60.0);
    const auto run = eval::runMethod(ds, "graph-uwb-odom", 1);
    ASSERT_TRUE(run.statistics.estimated_range_sigma.has_value()) << sigma;
    std::printf("[ NOISE    ] simulated sigma %.3f m, estimated %.4f m\n", sigma,
                *run.statistics.estimated_range_sigma);
    EXPECT_NEAR(*run.statistics.estimated_range_sigma, sigma, 0.15 * sigma);
    EXPECT_EQ(run.statistics.events.count("range_bias_estimated"), 0u) << sigma;
    ASSERT_EQ(run.statistics.estimated_noise.size(), 4u);
    for (const auto& [anchor, n] : run.statistics.estimated_noise) {
      EXPECT_NEAR(n.bias, 0.0, 0.05) << anchor;
      EXPECT_NEAR(n.sigma, sigma, 0.2 * sigma) << anchor;
    }
  }
}

// odom_noise=auto. The simulated room's odometry (0.02 m per metre at 10 Hz) is far finer than
// the smoother's model (0.01 m per increment plus 5 %), and its NLOS ranges pulled the path: the
// cross-validation tightens the model and the smoother ends near its own odometry. On the square
// loop, whose odometry reads every distance 4 % long, tightening would bend the ranges to the
// wrong path shape: the factor stays within a factor 2 of the model and the error with it.
TEST(OdometryNoise, CrossValidationTightensFineOdometryOnly) {
  auto rmse = [](const data::Dataset& ds, const std::string& m, double* factor) {
    const auto run = eval::runMethod(ds, m, 1);
    *factor = run.statistics.estimated_motion_scale.value_or(-1.0);
    const auto errors = eval::associate(run.trajectory, ds.ground_truth);
    return eval::computeMetrics(errors, run.trajectory, ds.ground_truth).rmse_2d;
  };
  double f = 0.0, f_model = 0.0, f_odom = 0.0;
  const double learnt = rmse(room(), "graph-uwb-odom", &f);
  const double model = rmse(room(), "graph-uwb-odom:odom_noise=1", &f_model);
  const double odom = rmse(room(), "odom", &f_odom);
  std::printf("[ ODO NOISE] room: factor %.4g, rmse %.4f m (model %.4f, odometry %.4f)\n", f,
              learnt, model, odom);
  EXPECT_LE(f, 0.125);
  EXPECT_LT(learnt, 0.5 * model);
  EXPECT_LT(learnt, 1.25 * odom);

  data::Dataset loop = test::makeSquareLoop(3, 0.1, 120.0);
  for (auto& e : loop.events)
    if (auto* o = std::get_if<loc::OdometryIncrement>(&e)) o->delta.head<2>() *= 1.04;
  const double loop_learnt = rmse(loop, "graph-uwb-odom", &f);
  const double loop_model = rmse(loop, "graph-uwb-odom:odom_noise=1", &f_model);
  const double loop_tight = rmse(loop, "graph-uwb-odom:odom_noise=0.0625", &f_model);
  std::printf(
      "[ ODO NOISE] loop, distances 4 %% long: factor %.4g, rmse %.4f m (model %.4f, "
      "1/16 %.4f)\n",
      f, loop_learnt, loop_model, loop_tight);
  EXPECT_GE(f, 0.5);
  EXPECT_LT(loop_learnt, 1.1 * loop_model);
}

// bias=auto: one anchor's ranges read 1 m long; the graph frees the biases, finds that one and
// tracks as well as without it.
TEST(SyntheticLoop, GraphFindsAnAnchorBias) {
  data::Dataset ds = test::makeSquareLoop(7, 0.1, 60.0);
  for (auto& e : ds.events)
    if (auto* r = std::get_if<uwb::Range>(&e); r && r->anchor_id == 2) r->range += 1.0;
  const auto run = eval::runMethod(ds, "graph-uwb-odom", 1);
  EXPECT_EQ(run.statistics.events.count("range_bias_estimated"), 1u);
  for (const auto& [anchor, n] : run.statistics.estimated_noise) {
    std::printf("[ BIAS     ] anchor %d: bias %+.3f m, sigma %.3f m\n", anchor, n.bias, n.sigma);
    EXPECT_NEAR(n.bias, anchor == 2 ? 1.0 : 0.0, 0.1) << anchor;
  }
  const auto errors = eval::associate(run.trajectory, ds.ground_truth);
  EXPECT_LT(eval::computeMetrics(errors, run.trajectory, ds.ground_truth).rmse_2d, 0.05);
}

// The particle filters learn the range model from a batch over the first seconds: with one
// anchor's ranges 1 m long and 0.3 m noise, uwb-pf finds the bias and the std, and tracks far
// better than with the model it starts from (calib=0: 0.15 m, no bias).
TEST(SyntheticLoop, ParticleFilterLearnsTheRangeModel) {
  data::Dataset ds = test::makeSquareLoop(11, 0.3, 90.0);
  for (auto& e : ds.events)
    if (auto* r = std::get_if<uwb::Range>(&e); r && r->anchor_id == 2) r->range += 1.0;
  auto rmse = [&](const eval::RunResult& run) {
    const auto errors = eval::associate(run.trajectory, ds.ground_truth);
    return eval::computeMetrics(errors, run.trajectory, ds.ground_truth).rmse_2d;
  };
  const auto learnt = eval::runMethod(ds, "uwb-pf", 1);
  const auto fixed = eval::runMethod(ds, "uwb-pf:calib=0", 1);
  std::printf("[ PF MODEL ] uwb-pf rmse_2d %.3f m learnt (sigma %.3f m), %.3f m without\n",
              rmse(learnt), learnt.statistics.estimated_range_sigma.value_or(-1.0), rmse(fixed));
  EXPECT_EQ(learnt.statistics.events.count("range_model_learnt"), 1u);
  // The model std is the one found before the biases are freed (it counts slow errors too), so
  // it lies between the noise and the noise with the bias spread; each anchor's own spread about
  // its bias is the noise.
  ASSERT_TRUE(learnt.statistics.estimated_range_sigma.has_value());
  EXPECT_GT(*learnt.statistics.estimated_range_sigma, 0.27);
  EXPECT_LT(*learnt.statistics.estimated_range_sigma, 0.6);
  ASSERT_EQ(learnt.statistics.estimated_noise.size(), 4u);
  for (const auto& [anchor, n] : learnt.statistics.estimated_noise) {
    EXPECT_NEAR(n.bias, anchor == 2 ? 1.0 : 0.0, 0.15) << anchor;
    EXPECT_NEAR(n.sigma, 0.3, 0.06) << anchor;
  }
  EXPECT_LT(rmse(learnt), 0.12);
  EXPECT_LT(rmse(learnt), 0.5 * rmse(fixed));
  // Every pose is produced once, in time order, although the first 60 s are filtered late.
  for (size_t i = 1; i < learnt.trajectory.size(); ++i)
    ASSERT_LT(learnt.trajectory[i - 1].t, learnt.trajectory[i].t);
  EXPECT_EQ(learnt.trajectory.size(), fixed.trajectory.size());
}

// A learning start is solved once per process for identical inputs: a second method with the
// same learner (uwb-ckf after uwb-ekf: sigma, q and bias auto) takes the first one's model and
// ends exactly where solving its own would; a moved anchor, a changed range, another seed or
// another learning span is solved afresh.
TEST(LearningStart, SharedByIdenticalStartsOnly) {
  const data::Dataset ds = test::makeSquareLoop(13, 0.2, 70.0);
  auto reused = [](const eval::RunResult& r) {
    return r.statistics.events.count("range_model_reused") != 0;
  };
  eval::setLearningCacheEnabled(false);
  const auto own = eval::runMethod(ds, "uwb-ckf", 1);
  EXPECT_FALSE(reused(own));
  eval::setLearningCacheEnabled(true);
  EXPECT_FALSE(reused(eval::runMethod(ds, "uwb-ekf", 1)));
  const auto shared = eval::runMethod(ds, "uwb-ckf", 1);
  EXPECT_TRUE(reused(shared));
  EXPECT_EQ(shared.statistics.events.at("range_model_learnt"), 1);
  ASSERT_EQ(shared.trajectory.size(), own.trajectory.size());
  for (size_t i = 0; i < own.trajectory.size(); ++i)
    ASSERT_EQ(shared.trajectory[i].pose, own.trajectory[i].pose) << i;
  EXPECT_EQ(shared.statistics.estimated_range_sigma, own.statistics.estimated_range_sigma);
  // A learner with another spec (uwb-ls has no q) is not the same start.
  EXPECT_FALSE(reused(eval::runMethod(ds, "uwb-ls", 1)));
  EXPECT_TRUE(reused(eval::runMethod(ds, "uwb-gn", 1)));
  data::Dataset moved = ds;
  moved.anchors[0].position.x() += 0.01;
  EXPECT_FALSE(reused(eval::runMethod(moved, "uwb-ekf", 1)));
  data::Dataset changed = ds;
  for (auto& e : changed.events)
    if (auto* r = std::get_if<uwb::Range>(&e)) {
      r->range += 0.001;
      break;
    }
  EXPECT_FALSE(reused(eval::runMethod(changed, "uwb-ekf", 1)));
  EXPECT_FALSE(reused(eval::runMethod(ds, "uwb-ekf", 2)));
  EXPECT_FALSE(reused(eval::runMethod(ds, "uwb-ekf:calib=30", 1)));
  EXPECT_TRUE(reused(eval::runMethod(ds, "uwb-ekf:calib=30", 1)));
}

// An estimator made outside the replay layer (a robot's own context, no cache) shares nothing:
// the library keeps no model from one run to the next. Given one cache, two runs share it.
TEST(LearningStart, SharedOnlyThroughTheContextsCache) {
  const data::Dataset ds = test::makeSquareLoop(13, 0.2, 70.0);
  auto events = [&](loc::EstimatorContext ctx) {
    auto est = loc::Registry::builtin().create("uwb-ekf", ctx);
    for (const auto& e : ds.events) est->process(e);
    est->finishAll();
    return est->statistics().events;
  };
  auto ctx = eval::makeContext(ds, 1);
  ctx.learning_cache = nullptr;
  for (int i = 0; i < 2; ++i) {
    const auto e = events(ctx);
    EXPECT_EQ(e.at("range_model_learnt"), 1);
    EXPECT_EQ(e.count("range_model_reused"), 0u) << i;
  }
  ctx.learning_cache = std::make_shared<loc::LearningCache>();
  EXPECT_EQ(events(ctx).count("range_model_reused"), 0u);
  EXPECT_EQ(events(ctx).count("range_model_reused"), 1u);
}

// The kidnapped robot in the simulated room (240 s, carried 8 s along its path, 2.4 m, at
// t = 100 s), with the defaults (relocalisation after 10 scans that do not fit): the
// fused filters find that the scans no longer fit the map at their best particle,
// spread their particles over the map again (event "relocalised") and recover, the ranges
// telling the room's symmetric twins apart. LiDAR alone (lidar-mcl) relocalises too, but may
// settle in a twin: printed, not asserted.
TEST(KidnappedRobot, LidarFiltersRelocaliseInTheRoom) {
  auto s =
      data::loadScenario(std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/pfibas_room.ini");
  s.duration = 240.0;
  const auto full = data::loadDataset(
      data::writeSimulation(s, 1, (test::scratchDir() / "kidnap_room").string()), "");
  const double t_kidnap = full.start_time + 100.0;
  const data::Dataset ds = test::kidnap(full, t_kidnap, 8.0);
  for (const std::string m : {"lidar-mcl", "fused-pf", "pf-sir", "pf-ibas"}) {
    const auto run = eval::runMethod(ds, m, 1);
    const bool asserted = m != "lidar-mcl";
    const auto recovery = test::recoveryTime(ds, run.trajectory, t_kidnap, 0.2, 5.0);
    const auto events = run.statistics.events;
    std::printf("[ KIDNAP   ] room %-10s relocalised %ld time, recovered after %.1f s\n", m.c_str(),
                events.count("relocalised") ? events.at("relocalised") : 0L,
                recovery.value_or(-1.0));
    EXPECT_GE(events.count("relocalised"), 1u) << m;
    if (!asserted) continue;
    ASSERT_TRUE(recovery.has_value()) << m << " never recovered";
    EXPECT_LT(*recovery, 30.0) << m;
  }
}

// A kidnapping in the 75 s room (carried 8 s along its path at t = 40 s; its ranges are 14 %
// NLOS, so the mixture is in force) with the scans' test off (lost_scans=0): under the range
// mixture learnt at the LiDAR's pose, more than half of the last 50 ranges failing the NLOS test
// says the filter is lost, and it relocalises; with that test off too (lost_ranges=0) nothing does.
TEST(KidnappedRobot, TheRangesAloneSayTheFusedFilterIsLost) {
  const auto s =
      data::loadScenario(std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/pfibas_room.ini");
  const auto full = data::loadDataset(
      data::writeSimulation(s, 1, (test::scratchDir() / "kidnap_room_ranges").string()), "");
  const double t_kidnap = full.start_time + 40.0;
  const data::Dataset ds = test::kidnap(full, t_kidnap, 8.0);
  for (const std::string m : {"fused-pf:lost_scans=0", "pf-ibas:lost_scans=0"}) {
    const auto run = eval::runMethod(ds, m, 1);
    const auto recovery = test::recoveryTime(ds, run.trajectory, t_kidnap, 0.2, 5.0);
    const auto& events = run.statistics.events;
    std::printf("[ KIDNAP   ] room %-22s relocalised %ld time, recovered after %.1f s\n", m.c_str(),
                events.count("relocalised") ? events.at("relocalised") : 0L,
                recovery.value_or(-1.0));
    EXPECT_EQ(events.count("range_mixture_at_lidar_pose"), 1u) << m;
    EXPECT_GE(events.count("relocalised"), 1u) << m;
    ASSERT_TRUE(recovery.has_value()) << m << " never recovered";
    EXPECT_LT(*recovery, 30.0) << m;
  }
  const auto blind = eval::runMethod(ds, "fused-pf:lost_scans=0,lost_ranges=0", 1);
  EXPECT_EQ(blind.statistics.events.count("relocalised"), 0u);
}

// A wheel slip in the simulated room (75 s; at t = 30 s the odometry reports a 25 deg turn the
// robot did not make). The cloud turns with it: no particle keeps the right heading and the scan
// alone cannot bring one there. The first scans that fit poorly re-draw half of the particles in
// a box as wide as the start's around the estimate (event scan_fit_respread), and the heading is
// back within 5 deg, held for 5 s, in a few seconds. Without that (respread=0) the filters stay
// turned until the motion noise or a relocalisation over the whole map finds the heading again.
TEST(HeadingSlip, APoorScanFitReDrawsTheCloudAroundTheEstimate) {
  const auto s =
      data::loadScenario(std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/pfibas_room.ini");
  data::Dataset ds = data::loadDataset(
      data::writeSimulation(s, 1, (test::scratchDir() / "slip_room").string()), "");
  const double t_slip = ds.start_time + 30.0;
  const double slip = 25.0 * M_PI / 180.0;
  const auto at = std::find_if(ds.events.begin(), ds.events.end(),
                               [&](const loc::Event& e) { return loc::eventTime(e) > t_slip; });
  ds.events.insert(at, loc::OdometryIncrement{t_slip, Eigen::Vector3d(0.0, 0.0, slip)});
  // Seconds from the slip until the heading error stays under 5 deg for 5 s; -1 if never.
  const auto recovery = [&](const std::vector<loc::PoseEstimate>& trajectory) {
    double since = -1.0;
    for (const auto& p : trajectory) {
      if (p.t < t_slip) continue;
      const auto gt = eval::interpolateGroundTruth(ds.ground_truth, p.t, 1.0);
      if (!gt) continue;
      if (std::abs(loc::wrapAngle(p.pose.z() - gt->z())) > 5.0 * M_PI / 180.0) {
        since = -1.0;
        continue;
      }
      if (since < 0.0) since = p.t;
      if (p.t - since >= 5.0) return since - t_slip;
    }
    return -1.0;
  };
  const auto count = [](const loc::EstimatorStatistics& st, const char* key) {
    return st.events.count(key) ? st.events.at(key) : 0L;
  };
  for (const std::string m : {"lidar-mcl", "fused-pf", "pf-sir", "pf-ibas"}) {
    // The defaults; then with the relocalisation over the map off, with and without re-spread.
    const auto run = eval::runMethod(ds, m, 1);
    const auto alone = eval::runMethod(ds, m + ":lost_scans=0", 1);
    const auto off = eval::runMethod(ds, m + ":lost_scans=0,respread=0", 1);
    const double with = recovery(run.trajectory), by_respread = recovery(alone.trajectory),
                 without = recovery(off.trajectory);
    std::printf(
        "[ SLIP     ] room %-10s heading back after %.1f s (%ld re-spreads, %ld "
        "relocalisations); without relocalising %.1f s, nor re-spreading %.1f s\n",
        m.c_str(), with, count(run.statistics, "scan_fit_respread"),
        count(run.statistics, "relocalised"), by_respread, without);
    EXPECT_GE(count(run.statistics, "scan_fit_respread"), 1) << m;
    EXPECT_GE(with, 0.0) << m << " never recovered its heading";
    EXPECT_LT(with, 5.0) << m;
    EXPECT_GE(by_respread, 0.0) << m << " never recovered its heading by re-spreading";
    EXPECT_LT(by_respread, 5.0) << m;
    EXPECT_TRUE(without < 0.0 || without > 2.0 * by_respread) << m << ": " << without << " s";
  }
}

// The guard itself: an estimator whose update produces NaN. process() drops the estimate,
// counts it, and resets the method.
class NanEstimator : public loc::Estimator {
 public:
  int resets = 0;

 protected:
  std::optional<loc::PoseEstimate> doProcess(const loc::Event& e) override {
    loc::PoseEstimate p;
    p.t = loc::eventTime(e);
    p.pose.x() = std::numeric_limits<double>::quiet_NaN();
    return p;
  }
  void reset() override { ++resets; }
};

TEST(Estimator, GuardDropsAndCountsANonFiniteEstimate) {
  NanEstimator est;
  uwb::Range r;
  r.t = 1.0;
  EXPECT_FALSE(est.process(r).has_value());
  EXPECT_FALSE(est.process(r).has_value());
  EXPECT_EQ(est.statistics().rejected.at("non_finite_estimate"), 2);
  EXPECT_EQ(est.statistics().resets, 2);
  EXPECT_EQ(est.resets, 2);
}

TEST(Registry, ListsEveryMethodWithDefaults) {
  const auto& reg = loc::Registry::builtin();
  for (const auto& name : reg.names()) {
    const auto* m = reg.find(name);
    ASSERT_NE(m, nullptr) << name;
    EXPECT_FALSE(m->description.empty());
  }
  const auto* ekf = reg.find("uwb-ekf");
  bool has_q = false;
  for (const auto& p : ekf->defaults) has_q |= p.key == "q" && p.value == "auto";
  EXPECT_TRUE(has_q);
}

TEST(Registry, SpecOverridesAndEffectiveParameters) {
  loc::EstimatorContext ctx;
  ctx.anchors = {{1, {0, 0, 0}}};
  const auto est = loc::Registry::builtin().create("uwb-kf:q=0.25,solver=gn", ctx);
  EXPECT_EQ(est->name(), "uwb-kf");
  std::map<std::string, std::string> eff;
  for (const auto& p : est->parameters()) eff[p.key] = p.value;
  EXPECT_EQ(eff["q"], "0.25");
  EXPECT_EQ(eff["solver"], "gn");
  // A config-file value is overridden by the spec.
  loc::ParamSet extra;
  extra.set("q", "0.9");
  extra.set("sigma", "0.3");
  const auto est2 = loc::Registry::builtin().create("uwb-kf:q=0.25", ctx, extra);
  for (const auto& p : est2->parameters()) eff[p.key] = p.value;
  EXPECT_EQ(eff["q"], "0.25");
  EXPECT_EQ(eff["sigma"], "0.3");
}

TEST(Registry, ErrorsNameTheProblem) {
  loc::EstimatorContext ctx;
  auto message = [&](const std::string& spec) {
    try {
      loc::Registry::builtin().create(spec, ctx);
    } catch (const loc::ParamError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("uwb-magic").find("unknown method 'uwb-magic'"), std::string::npos);
  EXPECT_NE(message("uwb-kf:qq=1").find("unknown parameter(s) qq"), std::string::npos);
  EXPECT_NE(message("uwb-kf:q=abc").find("'q' has invalid value 'abc'"), std::string::npos);
  EXPECT_NE(message("uwb-kf:q").find("expected key=value"), std::string::npos);
  EXPECT_NE(message("uwb-kf:solver=svd").find("solver"), std::string::npos);
  EXPECT_NE(message("uwb-ekf:iq=maybe").find("boolean"), std::string::npos);
  EXPECT_NE(message("uwb-hinf-ckf:hinf=0.5").find("'hinf'"), std::string::npos);
  EXPECT_NE(message("uwb-ins-ickf:k0=6").find("'k1' must exceed 'k0'"), std::string::npos);
}

namespace {

// The square loop's ground truth with its ranges replaced: four anchors answering in turn, one
// noise-free range every 0.13 s over the first 60 s (a round takes 0.52 s).
data::Dataset oneAnchorAtATime(data::Dataset ds) {
  ds.events.clear();
  const Eigen::Vector3d tag(0.1, 0.0, 1.0);
  for (int k = 0; 0.13 * k <= 60.0; ++k) {
    uwb::Range r;
    r.t = 0.13 * k;
    r.anchor_id = ds.anchors[static_cast<size_t>(k % 4)].id;
    r.tag_on_robot = tag;
    const auto truth = eval::interpolateGroundTruth(ds.ground_truth, r.t, 1.0);
    if (!truth) throw std::runtime_error("oneAnchorAtATime: no ground truth at a range");
    r.range = uwb::predictRange(*truth, tag, ds.anchors[static_cast<size_t>(k % 4)].position);
    ds.events.emplace_back(r);
  }
  ds.start_time = loc::eventTime(ds.events.front());
  ds.end_time = loc::eventTime(ds.events.back());
  return ds;
}

}  // namespace

TEST(EpochWindow, RangesOneAnchorAtATimeFormEpochsFromTheDataRate) {
  // A fixed 0.15 s window never holds three anchors; window=auto takes the span from the data.
  const data::Dataset ds = oneAnchorAtATime(test::makeSquareLoop(4, 0.05, 60.0));
  const auto fixed = eval::evaluateMethod(ds, "uwb-gn:window=0.15", 1, 1);
  const auto automatic = eval::evaluateMethod(ds, "uwb-gn", 1, 1);
  std::printf(
      "[ EPOCHS   ] one anchor at a time: window=0.15 coverage %.2f, auto coverage %.2f, "
      "rmse %.3f m\n",
      fixed.metrics.coverage, automatic.metrics.coverage, automatic.metrics.rmse_2d);
  EXPECT_EQ(fixed.metrics.steps, 0);
  EXPECT_GT(automatic.metrics.coverage, 0.9);
  EXPECT_LT(automatic.metrics.rmse_2d, 0.4);  // the tag moves 0.26 m during one round
}

// window=auto with several tags, by hand: three tags, four anchors, a round every 0.5 s. Tags in
// turn (each tag its four anchors, then the next tag, a range every 0.02 s) span 0.22 s a round;
// tags together (an anchor's three ranges at one instant, the anchors 0.06 s apart) span 0.18 s.
// The window is 1.2 times the span, and every closed epoch holds all 12 links. The gaps alone gave
// the 0.15 s minimum to both (tags together: two gaps in three are zero; in turn: 1.2 (4 - 1)
// 0.02 s), which split every round. One tag alone keeps the gap rule.
TEST(EpochWindow, SeveralTagsTakeTheWindowFromTheRoundTheyRangeIn) {
  auto feed = [](bool in_turn, int tags) {
    loc::EpochBuffer buffer(loc::AutoDouble{});
    std::vector<size_t> sizes;
    const int links = 4 * tags;
    for (int k = 0; k < 40 * links; ++k) {
      const int slot = k % links, round = k / links;
      loc::AcceptedRange r;
      r.measurement.anchor_id = in_turn ? slot % 4 : slot / tags;
      r.measurement.tag_id = in_turn ? slot / 4 : slot % tags;
      // Tags together share their anchor's instant; in turn, each range has its own.
      const int tick = in_turn || tags == 1 ? slot : (slot / tags) * tags;
      r.measurement.t = 100.0 + 0.5 * round + 0.02 * tick;
      if (auto epoch = buffer.add(r); epoch && round > 20) sizes.push_back(epoch->size());
    }
    return std::make_pair(buffer.window(), sizes);
  };
  for (bool in_turn : {false, true}) {
    const auto [window, sizes] = feed(in_turn, 3);
    // Tags together span 3 anchor instants (0.18 s); in turn, 11 ranges (0.22 s).
    EXPECT_NEAR(window, 1.2 * (in_turn ? 0.22 : 0.18), 1e-9) << in_turn;
    ASSERT_FALSE(sizes.empty());
    for (size_t n : sizes) EXPECT_EQ(n, 12u) << in_turn;
  }
  const auto [window, sizes] = feed(false, 1);
  EXPECT_NEAR(window, loc::EpochBuffer::kMinEpochWindow, 1e-9);
  for (size_t n : sizes) EXPECT_EQ(n, 4u);
}

// A fix from ranges taken one anchor at a time stands for the tag at their mean time: four
// ranges 0.13 s apart are stamped at the second and third's midpoint, not at the last.
TEST(EpochWindow, AnEpochIsStampedAtTheMeanTimeOfItsRanges) {
  std::vector<loc::AcceptedRange> epoch(4);
  for (size_t i = 0; i < epoch.size(); ++i)
    epoch[i].measurement.t = 1.7e9 + 0.13 * static_cast<double>(i);
  EXPECT_NEAR(loc::epochTime(epoch), 1.7e9 + 0.195, 1e-6);
  epoch.resize(1);
  EXPECT_EQ(loc::epochTime(epoch), 1.7e9);
}

// The same one-anchor-at-a-time ranges, noise-free, from a tag driving the square at 3 m/s (CMU
// Plaza2's speed): stamped at the last range, every fix lagged 0.195 s (rmse 0.598 m); at the mean
// time, 0.241 m with each range as taken (deskew=0), and 0.149 m with deskew (uwb-kf 0.241 ->
// 0.151 m). On these 4 m sides the velocity turns within an epoch, and what helps here is mostly
// the lower weight deskew gives the ranges farthest from the epoch's time (0.138 m with that
// alone, 0.227 m with the ranges moved alone); the next test checks the move itself.
TEST(EpochWindow, FastTagFixesDoNotLagTheirRanges) {
  data::Dataset fast = test::makeSquareLoop(4, 0.05, 360.0);
  for (auto& p : fast.ground_truth) p.t /= 6.0;  // 0.5 m/s -> 3 m/s
  const data::Dataset ds = oneAnchorAtATime(fast);
  for (const char* m : {"uwb-gn:deskew=0", "uwb-gn", "uwb-kf:deskew=0", "uwb-kf"}) {
    const auto run = eval::evaluateMethod(ds, m, 1, 1);
    std::printf("[ EPOCHS   ] tag at 3 m/s, one anchor every 0.13 s: %-16s rmse %.3f m\n", m,
                run.metrics.rmse_2d);
  }
  const auto gn = eval::evaluateMethod(ds, "uwb-gn", 1, 1);
  EXPECT_GT(gn.metrics.coverage, 0.9);
  EXPECT_LT(gn.metrics.rmse_2d, 0.2);
}

// The square five times larger (20 m sides, anchors 40 m apart) at 3 m/s, one range every
// 0.13 s: on its long sides the skew is first order, and moving each range to the epoch's time
// along the track's velocity takes the fixes from 0.231 m to 0.081 m (uwb-kf: 0.232 -> 0.086 m).
TEST(EpochWindow, RangesAreMovedToTheEpochTimeAlongTheTrack) {
  data::Dataset large = test::makeSquareLoop(4, 0.05, 75.0);
  for (auto& a : large.anchors) a.position.head<2>() *= 5.0;
  for (auto& p : large.ground_truth) {
    p.pose.head<2>() *= 5.0;
    p.t /= 6.0 / 5.0;  // 2.5 m/s on the larger square -> 3 m/s
  }
  const data::Dataset ds = oneAnchorAtATime(large);  // 60 s of ranges
  std::map<std::string, double> rmse;
  for (const char* m : {"uwb-gn:deskew=0", "uwb-gn", "uwb-kf:deskew=0", "uwb-kf"}) {
    const auto run = eval::evaluateMethod(ds, m, 1, 1);
    std::printf("[ EPOCHS   ] 20 m square at 3 m/s, one anchor every 0.13 s: %-16s rmse %.3f m\n",
                m, run.metrics.rmse_2d);
    EXPECT_GT(run.metrics.coverage, 0.9) << m;
    rmse[m] = run.metrics.rmse_2d;
  }
  // Only the variance the velocity adds (the ranges as taken): 0.164 / 0.166 m.
  EXPECT_LT(rmse["uwb-gn"], 0.12);
  EXPECT_LT(rmse["uwb-kf"], 0.12);
}

// deskewRanges, by hand: the tag at the origin at t = 0.5 s moving at 2 m/s along x; ranges from
// anchors ahead (taken 0.5 s before), abeam, and behind (taken 0.5 s after).
TEST(EpochWindow, DeskewMovesEachRangeToTheEpochTime) {
  const std::vector<Eigen::Vector2d> anchors = {{10, 0}, {0, 10}, {-10, 0}};
  const std::vector<double> stamps = {0.0, 0.5, 1.0};
  std::vector<loc::AcceptedRange> epoch(3);
  std::vector<uwb::PlanarRange> planar(3);
  for (size_t i = 0; i < 3; ++i) {
    epoch[i].measurement.t = stamps[i];
    const Eigen::Vector2d tag(2.0 * (stamps[i] - 0.5), 0.0);  // where the tag was at the range
    planar[i] = {anchors[i], (tag - anchors[i]).norm(), 0.1};
  }
  loc::FixContinuity::Motion motion{Eigen::Vector2d::Zero(), Eigen::Vector2d(2.0, 0.0),
                                    Eigen::Matrix2d::Zero()};
  // A sure velocity: every range as it would read at 0.5 s, 10 m.
  auto moved = loc::deskewRanges(epoch, planar, 0.5, motion);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_NEAR(moved[i].range, 10.0, 1e-12) << i;
    EXPECT_NEAR(moved[i].sigma, 0.1, 1e-12) << i;
  }
  EXPECT_NEAR(planar[0].range, 11.0, 1e-12);
  // Velocity std 1 m/s per axis (tr C_v = 2, |v|^2 = 4): half the velocity, and the ranges'
  // variance grows by (u^T C_v u) dt^2 = 0.25.
  motion.velocity_cov = Eigen::Matrix2d::Identity();
  moved = loc::deskewRanges(epoch, planar, 0.5, motion);
  EXPECT_NEAR(moved[0].range, 10.5, 1e-12);
  EXPECT_NEAR(moved[2].range, 10.5, 1e-12);
  EXPECT_NEAR(moved[0].sigma, std::sqrt(0.01 + 0.25), 1e-12);
  EXPECT_NEAR(moved[1].sigma, 0.1, 1e-12);  // taken at the epoch's time
  // A velocity no surer than its size (tr C_v = |v|^2) moves nothing.
  motion.velocity_cov = 2.0 * Eigen::Matrix2d::Identity();
  moved = loc::deskewRanges(epoch, planar, 0.5, motion);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(moved[i].range, planar[i].range) << i;
    EXPECT_EQ(moved[i].sigma, planar[i].sigma) << i;
  }
}

TEST(Registry, ParametersOutsideTheirLimitsAreErrors) {
  // The inputs that used to run out of memory, hang or score nonsense.
  loc::EstimatorContext ctx;
  ctx.anchors = {{1, {0, 0, 0}}};
  ctx.initial_pose = Eigen::Vector3d::Zero();
  for (const auto& [spec, key] : std::vector<std::pair<std::string, std::string>>{
           {"uwb-pf:n=1000000000", "'n'"},
           {"uwb-pf:a3=1e308", "'a3'"},
           {"lidar-icp:min_dist=-1", "'min_dist'"},
           {"uwb-kf:q=-1", "'q'"},
           {"uwb-ekf:sigma=0", "'sigma'"},
           {"uwb-ekf:sigma=inf", "'sigma'"},
           {"uwb-gn:window=-2", "'window'"},
           {"uwb-ckf:start_sigma_yaw=1e300", "'start_sigma_yaw'"}}) {
    try {
      loc::Registry::builtin().create(spec, ctx);
      ADD_FAILURE() << spec << " was accepted";
    } catch (const loc::ParamError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

TEST(Registry, EveryDefaultIsInsideItsLimits) {
  for (const auto& m : loc::Registry::builtin().methods())
    for (const auto& p : m.defaults) {
      char* end = nullptr;
      const double v = std::strtod(p.value.c_str(), &end);
      if (end == p.value.c_str() || *end != '\0') continue;  // not a number (enum, spec, auto)
      EXPECT_NO_THROW(loc::checkLimit(m.name, p.key, v)) << m.name << " " << p.key << "=" << v;
    }
}

// The adaptive filters coupled tightly (mode=ranges: a Sage-Husa statistic per anchor on each
// range's innovation) run on the room with full coverage and no NaN; their accuracy there is
// printed and bounded like the other methods'. The tight IAKF is not stable here: its divergence
// test (eq. 20 with gamma = 1 on one range's innovation, which a correct model exceeds a third of
// the time) fires on 648 of 2222 ranges, and each firing inflates the whole predicted covariance.
// Its RMSE has moved by half a metre with changes of 1e-9 in the learnt sigma, and lay at
// 1.09-1.58 m with R̂ from the innovation; with R̂ from the residual (the default since) and
// uwb-ekf's quarantine it is 3.21 m, while it improved on 15 of the other 18 benchmark datasets
// (the MRPT demo 5.43 -> 0.225 m). Its bound only catches a run that is lost outright; the
// instability is an open item of the adaptive-filter work, not a property this test asserts.
// uwb-akf: 0.214 m with the starting statistics weighted, 0.187 m with R̂ from the residual.
TEST(AdaptiveKalman, TightlyCoupledModeRunsOnTheRoom) {
  const std::map<std::string, double> bound = {{"uwb-akf:mode=ranges", 0.3},
                                               {"uwb-iakf:mode=ranges", 4.5}};
  for (const auto& [m, rmse_bound] : bound) {
    const auto run = eval::runMethod(room(), m, 1);
    const auto metrics = eval::computeMetrics(eval::associate(run.trajectory, room().ground_truth),
                                              run.trajectory, room().ground_truth);
    std::printf("[ ROOM     ] %-20s rmse_2d %.4f m, coverage %.3f\n", m.c_str(), metrics.rmse_2d,
                metrics.coverage);
    EXPECT_GE(metrics.coverage, 0.9) << m;
    EXPECT_LT(metrics.rmse_2d, rmse_bound) << m;
    EXPECT_EQ(run.statistics.rejected.count("non_finite_estimate"), 0u) << m;
  }
}

// The starting statistics count as 1/(1-b) steps (prior_steps=auto). At k = 0, the paper's d_0 = 1,
// the first innovation replaces them: R̂ = e^2 - H P H^T with P still the start's is negative,
// R̂ drops to r_floor, and the tight filter follows single ranges away (static_los, R̂ from the
// innovation: 0.205 m against 0.057 m; before the gate's floor of sigma^2 and the quarantine,
// 0.674 m). R̂ from the residual, the tight default, cannot go negative and needs no such start
// (0.067 m against 0.056 m). On the fix (greenhouse R1): 0.069 against 0.098 m.
TEST(AdaptiveKalman, StartingStatisticsCountAsTheirMemory) {
  auto rmse = [](const data::Dataset& ds, const std::string& spec) {
    const auto m = eval::evaluateMethod(ds, spec, 1, 1).metrics;
    std::printf("[ PRIOR    ] %-40s rmse_2d %.4f m, coverage %.3f\n", spec.c_str(), m.rmse_2d,
                m.coverage);
    EXPECT_GE(m.coverage, 0.9) << spec;
    return m.rmse_2d;
  };
  const auto still = test::simulatedScenario("static_los", 1);
  EXPECT_LT(rmse(still, "uwb-akf:mode=ranges"), 0.1);
  EXPECT_LT(rmse(still, "uwb-akf:mode=ranges,prior_steps=0"), 0.1);
  const double tight = rmse(still, "uwb-akf:mode=ranges,r_from=innovation");
  EXPECT_LT(tight, 0.1);
  EXPECT_GT(rmse(still, "uwb-akf:mode=ranges,r_from=innovation,prior_steps=0"), 3.0 * tight);
  const auto r1 = test::simulatedScenario("greenhouse_r1", 1);
  // With R̂ floored at the fixes' own noise (r_floor_fix, the default) the first innovation can no
  // longer take it to 1 cm: 0.061 against 0.064 m. Without that floor: 0.069 against 0.098 m.
  EXPECT_LT(rmse(r1, "uwb-akf:r_floor_fix=0"),
            0.8 * rmse(r1, "uwb-akf:r_floor_fix=0,prior_steps=0"));
}

// On the fix, the noise means cannot be told from the state: with r̂ the filter that has fallen
// behind learns its lag as the fixes' bias and stays there; q̂ integrates the corrections. On a
// 10-minute square loop (corners every 8 s, ranges 0.2 m), estimating both (means=qr, eq. 16 as
// printed) leaves uwb-akf and uwb-iakf behind the defaults, which estimate neither: 0.279 and
// 0.276 m against 0.185 and 0.186 m, and since Q̂ keeps the model's floor and the statistics
// start with 1/(1-b) steps' weight, 0.180 and 0.186 m against 0.174 and 0.185 m (the mean
// starts at zero with that weight too, and drifts less; CARMEN aces+uwb: 0.414 and 0.476 m
// against 0.381 and 0.381 m).
TEST(AdaptiveKalman, TheNoiseMeansAreNotEstimatedOnTheFix) {
  const data::Dataset ds = test::makeSquareLoop(17, 0.2, 600.0);
  auto rmse = [&](const std::string& spec) {
    const auto run = eval::runMethod(ds, spec, 1);
    const auto m = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth),
                                        run.trajectory, ds.ground_truth);
    std::printf("[ MEANS    ] %-24s rmse_2d %.4f m\n", spec.c_str(), m.rmse_2d);
    EXPECT_GE(m.coverage, 0.9) << spec;
    return m.rmse_2d;
  };
  for (const std::string m : {"uwb-akf", "uwb-iakf"}) {
    const double with_means = rmse(m + ":means=qr");
    const double defaults = rmse(m);
    EXPECT_LT(defaults, with_means) << m;
    EXPECT_DOUBLE_EQ(defaults, rmse(m + ":means=none"));
  }
}

// r_from on the fix, with the positivity guard alone (r_floor_fix=0): R̂ from the post-fit
// residual (eps eps' + H P H', positive by construction) never needs the guard, where R̂ from the
// innovation (e e' - H P H') may: uwb-iakf,
// whose divergence test inflates P, needs it at 1038 of 1200 fixes here (uwb-akf at none). The
// option was once silently ignored on the fix: both runs were the innovation's.
TEST(AdaptiveKalman, TheResidualOptionIsHonouredOnTheFix) {
  const data::Dataset ds = test::makeSquareLoop(17, 0.2, 120.0);
  for (const std::string m : {"uwb-akf", "uwb-iakf"}) {
    const auto innovation = eval::runMethod(ds, m + ":r_floor_fix=0", 1);
    const auto residual = eval::runMethod(ds, m + ":r_floor_fix=0,r_from=residual", 1);
    auto guarded = [](const eval::RunResult& run) {
      const auto it = run.statistics.events.find("r_kept_positive");
      return it == run.statistics.events.end() ? 0L : it->second;
    };
    std::printf("[ R FROM   ] %s: R kept positive %ld times (innovation), %ld (residual)\n",
                m.c_str(), guarded(innovation), guarded(residual));
    if (m == "uwb-iakf") {
      EXPECT_GT(guarded(innovation), 100);
    }
    EXPECT_EQ(guarded(residual), 0) << m;
    ASSERT_FALSE(innovation.trajectory.empty()) << m;
    ASSERT_EQ(innovation.trajectory.size(), residual.trajectory.size()) << m;
    EXPECT_GT((innovation.trajectory.back().pose - residual.trajectory.back().pose).norm(), 1e-6)
        << m << ": the residual's R̂ gave the innovation's track";
  }
}

// r_floor_fix: R̂ from the innovations falls below the fixes' own noise wherever P carries Q̂'s
// floor or the divergence test's inflation, and uwb-iakf then kept it at the 0.01 m guard and
// followed every fix. Floored at each fix's variance along its best-determined axis, it smooths
// them: uwb-akf 0.1171 -> 0.1068 m, uwb-iakf 0.1809 -> 0.1689 m on the square at 0.2 m noise.
TEST(AdaptiveKalman, TheEstimatedRIsKeptAtTheFixesOwnNoise) {
  const data::Dataset ds = test::makeSquareLoop(17, 0.2, 120.0);
  for (const std::string m : {"uwb-akf", "uwb-iakf"}) {
    auto rmse = [&](const std::string& spec) {
      const auto run = eval::runMethod(ds, spec, 1);
      return eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth), run.trajectory,
                                  ds.ground_truth)
          .rmse_2d;
    };
    const double floored = rmse(m), guard_only = rmse(m + ":r_floor_fix=0");
    std::printf("[ R FLOOR  ] %s: rmse_2d %.4f m at the fixes' noise, %.4f m at the guard alone\n",
                m.c_str(), floored, guard_only);
    EXPECT_LT(floored, 0.95 * guard_only) << m;
  }
}

// Greenhouse R3 (every range 1 m long under 1 m noise): uwb-akf and uwb-iakf correct the ranges
// by the biases their learning start finds (calib_bias=auto, the default of both). Measured:
// uwb-akf 0.878 m with biases of +0.95 m (1.827 m with calib_bias=0), uwb-iakf 0.889 m.
TEST(AdaptiveKalman, TakeTheBiasesTheirLearningStartFinds) {
  const auto ds = test::simulatedScenario("greenhouse_r3", 1);
  for (const std::string m : {"uwb-akf", "uwb-iakf"}) {
    const auto run = eval::runMethod(ds, m, 1);
    const auto metrics = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth),
                                              run.trajectory, ds.ground_truth);
    std::printf("[ AKF BIAS ] %s: rmse_2d %.3f m\n", m.c_str(), metrics.rmse_2d);
    EXPECT_LT(metrics.rmse_2d, 1.2) << m;
    ASSERT_EQ(run.statistics.estimated_noise.size(), ds.anchors.size()) << m;
    for (const auto& [id, noise] : run.statistics.estimated_noise)
      EXPECT_NEAR(noise.bias, 1.0, 0.3) << m << " anchor " << id;
  }
}

// The --set parser: "method.key=value" split at the last dot before the '='; malformed text and
// unknown methods are errors naming the token.
TEST(Registry, SetOverridesParseAndRefuseWhatIsNoOverride) {
  const auto& reg = loc::Registry::builtin();
  const auto o = loc::SetOverride::parse("pf-ibas+graph.front=pf-sir:n=50", reg);
  EXPECT_EQ(o.method, "pf-ibas+graph");
  EXPECT_EQ(o.key, "front");
  EXPECT_EQ(o.value, "pf-sir:n=50");
  const auto v = loc::SetOverride::parse("uwb-kf.q=0.5", reg);
  EXPECT_EQ(v.method, "uwb-kf");
  EXPECT_EQ(v.value, "0.5");
  for (const std::string bad : {"uwb-kf", "uwb-kf.q", ".q=1", "uwb-kf.=1", "q=1"})
    test::expectErrorMentions<loc::ParamError>([&] { loc::SetOverride::parse(bad, reg); },
                                               {"method.key=value"});
  test::expectErrorMentions<loc::ParamError>([&] { loc::SetOverride::parse("uwb-kff.q=1", reg); },
                                             {"uwb-kff", "not a method", "uwb-kf"});
}

// ---- The point-based filters and the improved Sage-Husa KF ----

// The federated filter with one local filter and without the fold's blind update is uwb-ekf:
// same prediction, gate, quarantine and update, and the fusion of one filter is that filter.
TEST(PointFilters, FederatedWithOneGroupIsTheEkf) {
  const auto ekf = eval::runMethod(room(), "uwb-ekf", 1);
  const auto fed = eval::runMethod(room(), "federated-ekf:groups=1,fold_blind=0", 1);
  ASSERT_EQ(ekf.trajectory.size(), fed.trajectory.size());
  for (std::size_t i = 0; i < ekf.trajectory.size(); ++i)
    ASSERT_LT((ekf.trajectory[i].pose - fed.trajectory[i].pose).norm(), 1e-9) << i;
}

// A 40 s range outage on the square loop (60-100 s; the robot drives 20 m meanwhile): the
// predicted position spreads over metres, so the range filters restart from a fix
// (reinitialised_after_outage) instead of updating a metres-wide prediction with one range at a
// time, and track from there. Measured after 105 s: 0.053-0.056 m, uwb-iahckf 0.171 m; without
// the restart (reinit_std=0) uwb-ckf 0.680, uwb-srukf 1.477 and uwb-iahckf 3.260 m.
TEST(PointFilters, RestartFromAFixAfterARangeOutage) {
  data::Dataset ds = test::makeSquareLoop(5, 0.1, 180.0);
  ds.events.erase(std::remove_if(ds.events.begin(), ds.events.end(),
                                 [](const loc::Event& e) {
                                   const auto* r = std::get_if<uwb::Range>(&e);
                                   return r && r->t >= 60.0 && r->t < 100.0;
                                 }),
                  ds.events.end());
  std::vector<data::TimedPose> after;
  std::copy_if(ds.ground_truth.begin(), ds.ground_truth.end(), std::back_inserter(after),
               [](const auto& g) { return g.t >= 105.0; });
  for (const std::string m : {"uwb-ekf", "uwb-ckf", "uwb-hinf-ckf", "uwb-iahckf", "uwb-srukf",
                              "uwb-shkf", "federated-ekf"}) {
    const auto run = eval::runMethod(ds, m, 1);
    const auto metrics =
        eval::computeMetrics(eval::associate(run.trajectory, after), run.trajectory, after);
    EXPECT_GT(metrics.coverage, 0.95) << m;
    EXPECT_LT(metrics.rmse_2d, 0.25) << m;
    EXPECT_GE(run.statistics.events.count("reinitialised_after_outage"), 1u) << m;
  }
}

// The fold of a range over the cubature points, by hand: anchors at (0, -3) and (0, 3) on the
// tag's plane, the mean on their line at the origin with std 1 m across it (x) and 0.1 m along
// it. The points +-2 m across lie 2 m from the line, where the range to either anchor is
// sqrt(4 + 9) = 3.606 m against 3 m at the mean: 0.606 m longer on both sides, a fold across x.
// Along the line the range changes sign (+-0.2 m), no fold; with 0.1 m across, the fold is
// 0.0067 m deep, under a 0.1 m std; 5 m off the line the range grows on one side only.
// The mean's side: on the line the range at the mean is the least along x (side unknown); 0.5 m
// off it with std 1 m (points at 2.5 and -1.5 m: 3.905 and 3.354 m against 3.041 m, a fold) it
// exceeds the least, 3 m, by 0.041 m, within 3 stds (0.3 m); 1.5 m off with std 2 m (points at
// 5.5 and -2.5 m: 6.265 and 3.905 against 3.354 m) by 0.354 m, beyond 3 stds but within 4.
TEST(PointFilters, RangeFoldByHand) {
  loc::AcceptedRange r;
  r.measurement.anchor_id = 1;
  r.anchor = Eigen::Vector3d(0.0, 3.0, 0.0);
  r.measurement.tag_on_robot = Eigen::Vector3d::Zero();
  const auto fold = [&](double x, double std_x, double side_sigmas = 3.0) {
    loc::kalman::Vec<4> mean(x, 0.0, 0.0, 0.0);
    const loc::kalman::Mat<4, 4> p = Eigen::Vector4d(std_x * std_x, 0.01, 0.01, 0.01).asDiagonal();
    return loc::rangeFold(loc::kalman::cubaturePoints<4>(mean, p), mean, r, 0.1, side_sigmas);
  };
  const auto across = fold(0.0, 1.0);
  ASSERT_TRUE(across.has_value());
  EXPECT_NEAR(std::abs(across->axis.x()), 1.0, 1e-12);
  EXPECT_NEAR(across->axis.y(), 0.0, 1e-12);
  EXPECT_FALSE(across->side_known);
  EXPECT_FALSE(fold(0.0, 0.1).has_value());
  EXPECT_FALSE(fold(5.0, 1.0).has_value());
  const auto near = fold(0.5, 1.0);
  ASSERT_TRUE(near.has_value());
  EXPECT_NEAR(std::abs(near->axis.x()), 1.0, 1e-12);
  EXPECT_FALSE(near->side_known);
  const auto off = fold(1.5, 2.0);
  ASSERT_TRUE(off.has_value());
  EXPECT_NEAR(std::abs(off->axis.x()), 1.0, 1e-12);
  EXPECT_TRUE(off->side_known);
  EXPECT_FALSE(fold(1.5, 2.0, 4.0)->side_known);
  // The unscented set (the mean first) folds the same way.
  loc::kalman::Vec<4> mean = loc::kalman::Vec<4>::Zero();
  const loc::kalman::Mat<4, 4> p = Eigen::Vector4d(1.0, 0.01, 0.01, 0.01).asDiagonal();
  const auto unscented = loc::rangeFold(
      loc::kalman::unscentedPoints<4>(mean, loc::kalman::lowerSquareRoot<4>(p), 1.0, 2.0, 0.0),
      mean, r, 0.1, 3.0);
  ASSERT_TRUE(unscented.has_value());
  EXPECT_NEAR(std::abs(unscented->axis.x()), 1.0, 1e-12);
}

// The MRPT demo: beacon 1 reads metres short at 78-90 s and 300-320 s, while the robot crosses
// the line through beacons 2 and 3. Their ranges fold over the state's spread across that line:
// the cubature filter's P_xz vanishes and its spread grows until it restarts, and the range's
// slope at the mean throws it across the line, to the mirror side, in either direction (the
// federated filter's locals, on a share of the information, the furthest). Blind across the
// fold while the mean is near it (fold_blind, the default), the filters carry the position
// across on their velocity. Measured (without the manifest's sigma / with it), fold_blind=0 ->
// 1: uwb-ckf 0.231 / 0.272 -> 0.183 / 0.188 m, uwb-srukf 0.226 / 0.268 -> 0.177 / 0.178,
// uwb-hinf-ckf 0.255 / 0.327 -> 0.184 / 0.185, uwb-iahckf 0.259 / 0.263 -> 0.251 / 0.238,
// federated-ekf 1.078 / 1.069 -> 0.184 / 0.183 m.
// Blind on every folding range (before the mean's side was told), the spread along the fold
// grew while blind and the points folded ever more: with no restart after an outage
// (reinit_std=0) every filter was lost for good, 4.7-5.3 m (blind_across_fold 463 times for
// uwb-ckf); linearised at the mean once the range tells its side, 0.18-0.28 m.
TEST(PointFilters, CarryThePositionAcrossTheFoldOfTwoAnchors) {
  auto ds = data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  const std::map<std::string, double> bound = {{"uwb-ckf", 0.22},
                                               {"uwb-srukf", 0.22},
                                               {"uwb-hinf-ckf", 0.22},
                                               {"uwb-iahckf", 0.27},
                                               {"federated-ekf", 0.22}};
  // The run's RMSE; `event` was counted (or, with fold_blind=0, neither fold event).
  const auto rmseOf = [&](const std::string& spec, const char* event) {
    const auto run = eval::runMethod(ds, spec, 1);
    const auto metrics = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth),
                                              run.trajectory, ds.ground_truth);
    EXPECT_GT(metrics.coverage, 0.95) << spec;
    const auto& events = run.statistics.events;
    if (event) {
      EXPECT_EQ(events.count(event), 1u) << spec << " " << event;
    } else {
      EXPECT_EQ(events.count("blind_across_fold") + events.count("linearised_at_fold"), 0u) << spec;
    }
    return metrics.rmse_2d;
  };
  for (const bool manifest_sigma : {true, false}) {
    if (!manifest_sigma) ds.manifest.uwb_sigma.reset();
    for (const auto& [m, most] : bound) {
      const double plain = rmseOf(m + ":fold_blind=0", nullptr);
      const double blind = rmseOf(m + ":fold_blind=1", "blind_across_fold");
      const double kept = rmseOf(m + ":fold_blind=1,reinit_std=0", "linearised_at_fold");
      std::printf("[ FOLD     ] %s (%s): %.3f -> %.3f m; without restarts %.3f m\n", m.c_str(),
                  manifest_sigma ? "manifest sigma" : "defaults", plain, blind, kept);
      EXPECT_LT(blind, most) << m;
      EXPECT_LT(blind, plain - 0.005) << m;
      EXPECT_LT(kept, 0.35) << m;
    }
  }
}

// The robust and adaptive factors by hand: IGG-III (k0 2, k1 5) keeps R up to 2 std, inflates
// by (v / k0) ((k1 - k0) / (k1 - v))^2 between (v = 3: 1.5 x 2.25 = 3.375) and drops beyond 5;
// the Sage-Husa adaptive factor (c0 1, c1 3.5) is 0 for a slow change, linear between, 1 for
// a rapid one.
TEST(PointFilters, RobustAndAdaptiveFactorsByHand) {
  EXPECT_EQ(loc::iggIIIFactor(1.5, 2.0, 5.0), 1.0);
  EXPECT_NEAR(loc::iggIIIFactor(3.0, 2.0, 5.0), 3.375, 1e-12);
  EXPECT_TRUE(std::isinf(loc::iggIIIFactor(5.5, 2.0, 5.0)));
  EXPECT_EQ(loc::UwbShkf::adaptiveFactor(0.5, 1.0, 3.5), 0.0);
  EXPECT_NEAR(loc::UwbShkf::adaptiveFactor(2.0, 1.0, 3.5), 0.4, 1e-12);
  EXPECT_EQ(loc::UwbShkf::adaptiveFactor(4.0, 1.0, 3.5), 1.0);
}

namespace {

uwb::Range rangeAt(double t, int anchor, double range) {
  uwb::Range r;
  r.t = t;
  r.anchor_id = anchor;
  r.range = range;
  return r;
}

}  // namespace

// One uwb-shkf step by hand. Start at (0, 0) with P = diag(0.25, 0.25, 1, 1) (start_sigma 0.5);
// a range of 5.5 m to the anchor at (3, 4) at the start time (no motion, Q = 0) predicts 5,
// H = [-0.6 -0.8 0 0], e = 0.5, H P H^T = 0.25. The update uses the anchor's R̂ so far, the
// model's sigma^2 = 0.01: S = 0.26, K = P H^T / S, and the tag moves by
// K e = (-0.288462, -0.384615). Then R̂ (d_0 = 1, beta 0):
//   - from the residual (the default): ε = e - H K e = e R / S = 0.0192308, H P_k H^T =
//     H P H^T R / S = 0.0096154, R̂ = ε^2 + H P_k H^T = 0.0099852 (sigma 0.0999260);
//   - from the innovation (r_from=innovation, used in this update): C_exp = C_win = e^2 = 0.25,
//     fading 1, R = C - H P H^T = 0, kept at the model's sigma^2 = 0.01 while the anchor's
//     statistics hold fewer than n0 (10) innovations (above the floor (sigma / 2)^2); with n0=1
//     the first statistic already holds n0: R = 0 goes to the floor, 0.0025, and S = 0.2525.
// With bias=1 the anchor's bias becomes d_0 e = 0.5.
TEST(Shkf, OneStepByHand) {
  loc::EstimatorContext ctx;
  ctx.anchors = {{1, {-3, 0, 0}}, {2, {3, 4, 0}}, {3, {3, -4, 0}}};
  ctx.initial_pose = Eigen::Vector3d(0, 0, 0);
  // The start, then the range to anchor 2: the filter after it, and the pose it gave.
  const auto step = [&](const std::string& spec) {
    auto est = loc::Registry::builtin().create("uwb-shkf:sigma=0.1,iq=0,calib=0" + spec, ctx);
    EXPECT_TRUE(est->process(rangeAt(10.0, 1, 3.0)).has_value());
    const auto out = est->process(rangeAt(10.0, 2, 5.5));
    return std::make_pair(std::move(est), out.value_or(loc::PoseEstimate{}));
  };
  const auto check = [](const std::pair<std::unique_ptr<loc::Estimator>, loc::PoseEstimate>& run,
                        double s, const char* event, double sigma) {
    EXPECT_NEAR(run.second.pose.x(), 0.25 * -0.6 * 0.5 / s, 1e-9);
    EXPECT_NEAR(run.second.pose.y(), 0.25 * -0.8 * 0.5 / s, 1e-9);
    EXPECT_EQ(
        run.first->statistics().events.count(event) ? run.first->statistics().events.at(event) : 0,
        1)
        << event;
    EXPECT_NEAR(run.first->statistics().estimated_noise.at(2).sigma, sigma, 1e-12);
  };
  const auto residual = step("");
  EXPECT_NEAR(residual.second.pose.x(), 0.25 * -0.6 * 0.5 / 0.26, 1e-9);
  EXPECT_NEAR(residual.second.pose.y(), 0.25 * -0.8 * 0.5 / 0.26, 1e-9);
  const double eps = 0.5 * 0.01 / 0.26, hph = 0.25 * 0.01 / 0.26;
  EXPECT_NEAR(residual.first->statistics().estimated_noise.at(2).sigma, std::sqrt(eps * eps + hph),
              1e-12);
  EXPECT_NEAR(residual.first->statistics().estimated_noise.at(2).sigma, 0.0999260, 1e-7);
  EXPECT_EQ(residual.first->statistics().events.count("r_kept_positive"), 0u);
  check(step(",r_from=innovation"), 0.26, "r_kept_at_model_until_n0", 0.1);
  check(step(",r_from=innovation,n0=1"), 0.2525, "r_kept_positive", 0.05);
  // With the bias estimated, the first weight d_0 = 1 takes the whole innovation as the bias.
  EXPECT_NEAR(step(",bias=1").first->statistics().estimated_noise.at(2).bias, 0.5, 1e-12);
}

// R̂ of uwb-shkf and uwb-iahckf on a tag walking at up to 0.3 m/s round three anchors, each
// anchor's range once a second with 5 cm noise (the MRPT demo's rate), the model's sigma 5 cm.
// The process noise (calib=0: q 0.1 m^2/s^3) is wider than this walk's (accelerations of
// 0.05 m/s^2), and over a second H P H^T outgrows the ranges' noise. From the post-fit residual
// (the default) each anchor's R̂ holds the ranges' noise (measured: uwb-shkf 0.046 / 0.045 /
// 0.043 m, uwb-iahckf 0.052 / 0.051 / 0.049 m, never at the floor); from the innovation
// (C - H P H^T, e^2 - P_zz) it is at its floor (sigma / 2) for 391 (uwb-shkf) and 372
// (uwb-iahckf) of the 603 ranges, and two anchors of each end there.
TEST(SageHusaFilters, TheResidualHoldsTheRangesNoiseWhereTheInnovationSitsAtTheFloor) {
  const auto at = [](double t) {
    const double w = 2.0 * M_PI * t / 40.0;
    return Eigen::Vector2d(4.0 + 2.0 * std::sin(w), 2.5 + std::cos(w));
  };
  const data::Dataset ds = threeAnchorWalk("walk_round_three", 200.0, 7, at,
                                           [&](double t, int) -> std::optional<Eigen::Vector2d> {
                                             if (std::fmod(t + 1e-6, 1.0) > 0.05)
                                               return std::nullopt;
                                             return at(t);
                                           });
  const auto floored = [](const loc::EstimatorStatistics& s) {
    return s.events.count("r_kept_positive") ? s.events.at("r_kept_positive") : 0;
  };
  for (const std::string m : {"uwb-shkf", "uwb-iahckf"}) {
    const auto residual = eval::runMethod(ds, m + ":sigma=0.05,calib=0", 1).statistics;
    EXPECT_EQ(floored(residual), 0) << m;
    ASSERT_EQ(residual.estimated_noise.size(), 3u) << m;
    for (const auto& [id, noise] : residual.estimated_noise) {
      std::printf("[ SH-R     ] %-10s anchor %d: sigma %.4f from the residual\n", m.c_str(), id,
                  noise.sigma);
      EXPECT_NEAR(noise.sigma, 0.05, 0.0125) << m << " " << id;
    }
    const auto innovation =
        eval::runMethod(ds, m + ":sigma=0.05,calib=0,r_from=innovation", 1).statistics;
    std::printf("[ SH-R     ] %-10s from the innovation: at the floor %ld times\n", m.c_str(),
                static_cast<long>(floored(innovation)));
    EXPECT_GT(floored(innovation), 150) << m;
    int at_floor = 0;
    for (const auto& [id, noise] : innovation.estimated_noise) {
      std::printf("[ SH-R     ] %-10s anchor %d: sigma %.4f from the innovation\n", m.c_str(), id,
                  noise.sigma);
      at_floor += std::abs(noise.sigma - 0.025) < 1e-9;
    }
    EXPECT_GE(at_floor, 1) << m;
  }
}

// Greenhouse R1 (38 s, 0.1 m noise with a 0.1 m bias), R̂ from the innovation: the first
// innovations of each anchor are mostly the start's uncertainty, and R̂ = C - H P H^T read off
// them fell to its floor; the overconfident filter then gated 612 ranges (3.93 m). Kept at the
// model's sigma^2 until n0 innovations, it scores 0.063 m. From the residual (the default),
// which no start's uncertainty drives below zero, 0.063 m too.
TEST(Shkf, KeepsTheModelsNoiseUntilItsStatisticsHoldN0Innovations) {
  const auto ds = test::simulatedScenario("greenhouse_r1", 1);
  for (const std::string m : {"uwb-shkf:r_from=innovation", "uwb-shkf"}) {
    const auto run = eval::runMethod(ds, m, 1);
    const auto metrics = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth),
                                              run.trajectory, ds.ground_truth);
    std::printf("[ SHKF-GH1 ] %-28s rmse_2d %.3f m\n", m.c_str(), metrics.rmse_2d);
    EXPECT_GT(metrics.coverage, 0.95) << m;
    EXPECT_LT(metrics.rmse_2d, 0.12) << m;
    if (m.find("innovation") != std::string::npos) {
      EXPECT_GE(run.statistics.events.count("r_kept_at_model_until_n0"), 1u);
    }
  }
}

// Greenhouse R3 (every range 1 m long under 1 m noise, no NLOS): no anchor's offset stands out
// of the noise, so uwb-pf's learning start finds the delay through its bias trial, one bias
// common to every anchor freed when it explains a quarter of the range variance. Measured:
// 0.188 m with biases of +0.95 m; 1.178 m without the trial (biases 0, sigma 1.37 m).
TEST(UwbPf, LearnsADelayCommonToEveryAnchorUnderTheNoise) {
  const auto ds = test::simulatedScenario("greenhouse_r3", 1);
  const auto run = eval::runMethod(ds, "uwb-pf", 1);
  const auto metrics = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth),
                                            run.trajectory, ds.ground_truth);
  std::printf("[ UWB-PF   ] greenhouse R3: rmse_2d %.3f m\n", metrics.rmse_2d);
  EXPECT_GT(metrics.coverage, 0.95);
  EXPECT_LT(metrics.rmse_2d, 0.35);
  ASSERT_EQ(run.statistics.estimated_noise.size(), ds.anchors.size());
  for (const auto& [id, noise] : run.statistics.estimated_noise) {
    std::printf("[ UWB-PF   ] anchor %d: bias %+.3f m, sigma %.3f m\n", id, noise.bias,
                noise.sigma);
    EXPECT_NEAR(noise.bias, 1.0, 0.3) << id;
  }
}

// The MRPT demo without its manifest's sigma: over uwb-pf's 60 s learning batch the odometry's
// path takes biases per anchor of +0.01 / -0.16 / +0.07 m (range std 0.107 -> 0.070 m, alike in
// both halves), where the reference gives -0.07 / -0.05 / -0.02 m over the run (`uwbloc
// calibrate --per anchor`); graph-uwb on the same ranges takes none, so they are left (event
// range_bias_unconfirmed): 0.139 m, against 0.269 m with them.
TEST(UwbPf, LeavesBiasesThatOnlyTheOdometrysPathTakes) {
  auto ds = data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  ds.manifest.uwb_sigma.reset();  // defaults only
  const auto run = eval::runMethod(ds, "uwb-pf", 1);
  const auto metrics = eval::computeMetrics(eval::associate(run.trajectory, ds.ground_truth),
                                            run.trajectory, ds.ground_truth);
  std::printf("[ UWB-PF   ] MRPT demo without its sigma: rmse_2d %.3f m\n", metrics.rmse_2d);
  EXPECT_EQ(run.statistics.events.count("range_bias_unconfirmed"), 1u);
  for (const auto& [id, noise] : run.statistics.estimated_noise) EXPECT_EQ(noise.bias, 0.0) << id;
  EXPECT_GT(metrics.coverage, 0.95);
  EXPECT_LT(metrics.rmse_2d, 0.18);
}

// The simulated PF-IBAS room's ranges (a share NLOS, in areas) are correlated from range to
// range: uwb-pf's learning start reads the share of independent information off the smoothed
// residuals (RangeMixture::weight, 1 / their autocorrelation time) and counts each range by it:
// 0.048 m, against 0.107 m with every range counted as independent (range_share=1).
TEST(UwbPf, CountsEachRangeByItsShareOfIndependentInformation) {
  const auto ds = test::simulatedScenario("pfibas_room", 1);
  const auto shared = eval::evaluateMethod(ds, "uwb-pf", 1, 1);
  const auto independent = eval::evaluateMethod(ds, "uwb-pf:range_share=1", 1, 1);
  ASSERT_TRUE(shared.estimated_range_mixture);
  std::printf(
      "[ UWB-PF   ] room: each range counted %.3f, rmse_2d %.3f m (%.3f m as independent)\n",
      shared.estimated_range_mixture->weight, shared.metrics.rmse_2d, independent.metrics.rmse_2d);
  EXPECT_LT(shared.estimated_range_mixture->weight, 0.5);
  EXPECT_GT(shared.metrics.coverage, 0.95);
  EXPECT_LT(shared.metrics.rmse_2d, independent.metrics.rmse_2d);
  EXPECT_LT(shared.metrics.rmse_2d, 0.07);
}

// Odometry at 1 Hz and ranges at 10 Hz, as on the MRPT demo with simulated tags: the particles
// are carried to each range's time at the last increment's rate (carry=1), so that a range is
// weighed where the robot is when it is taken, not up to a second (0.5 m) behind it: 0.112 m
// against 0.163 m. (Where the robot starts, stops or turns within an increment the carried
// motion is wrong until the next one: at 10 Hz odometry the same run scores 0.030 m.)
TEST(UwbPf, CarriesTheParticlesBetweenSlowOdometryIncrements) {
  auto scenario =
      data::loadScenario(std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/tracking_los.ini");
  scenario.odometry.rate = 1.0;
  scenario.uwb.sigma = 0.05;
  const auto dir = test::scratchDir() / "slow_odometry";
  const auto ds = data::loadDataset(data::writeSimulation(scenario, 1, dir.string()), "");
  const auto carried = eval::evaluateMethod(ds, "uwb-pf", 1, 1);
  const auto held = eval::evaluateMethod(ds, "uwb-pf:carry=0", 1, 1);
  std::printf("[ UWB-PF   ] 1 Hz odometry: rmse_2d %.3f m carried, %.3f m held\n",
              carried.metrics.rmse_2d, held.metrics.rmse_2d);
  EXPECT_GT(carried.metrics.coverage, 0.95);
  EXPECT_LT(carried.metrics.rmse_2d, 0.8 * held.metrics.rmse_2d);
  EXPECT_LT(carried.metrics.rmse_2d, 0.13);
}

// The odometry noise a1-a4 is learnt at the start (a_scale=auto). A field like CMU Plaza2's: 4
// anchors 40 x 30 m apart, ranges at 1 Hz per anchor with 0.5 m noise, the robot at 3 m/s.
// With odometry ten times better than the defaults assume, the ranges are likeliest under the
// smallest noise tried, and the filter takes it (0.244 m against 0.292 m at the defaults); with
// odometry ten times worse, the smaller noises make the ranges less likely and the defaults
// stay (with the trials' NLOS test rejecting instead of down-weighting, the evidence rose
// under the smallest noise, whose lost filter rejected the most ranges, and the run ended at
// 7.3 m).
TEST(UwbPf, LearnsTheOdometryNoiseFromTheLearningStartsRanges) {
  auto run = [](double odometry_noise, const std::string& name) {
    char text[1024];
    std::snprintf(text, sizeof text,
                  "[scenario]\nname = %s\ngt_rate = 10\nduration = 180\n"
                  "[anchors]\nanchor_1 = 0 0 1.0\nanchor_2 = 40 0 1.0\nanchor_3 = 40 30 1.0\n"
                  "anchor_4 = 0 30 1.0\n"
                  "[trajectory]\nwaypoints = 5 5, 35 5, 35 25, 5 25\nspeed = 3\n"
                  "[uwb]\nrate = 1\nsigma = 0.5\ntag = 0 0 1.0\n"
                  "[odometry]\nrate = 10\nsigma_xy_per_m = %g\nsigma_theta_per_rad = %g\n"
                  "sigma_theta_per_m = %g\n",
                  name.c_str(), 0.02 * odometry_noise, 0.02 * odometry_noise,
                  0.005 * odometry_noise);
    const auto dir = test::scratchDir() / name;
    std::filesystem::create_directories(dir);
    const auto ini = test::writeText(dir / "scenario.ini", text);
    const auto ds = data::loadDataset(
        data::writeSimulation(data::loadScenario(ini), 1, (dir / "out").string()), "");
    return std::make_pair(eval::evaluateMethod(ds, "uwb-pf", 1, 1),
                          eval::evaluateMethod(ds, "uwb-pf:a_scale=1", 1, 1));
  };
  const auto [good, good_fixed] = run(0.1, "good_odometry");
  const auto [poor, poor_fixed] = run(10.0, "poor_odometry");
  std::printf(
      "[ UWB-PF   ] good odometry: scale %.4g, rmse_2d %.3f m (%.3f m at 1); poor: scale "
      "%.4g, %.3f m (%.3f m at 1)\n",
      good.estimated_motion_scale.value_or(-1.0), good.metrics.rmse_2d, good_fixed.metrics.rmse_2d,
      poor.estimated_motion_scale.value_or(-1.0), poor.metrics.rmse_2d, poor_fixed.metrics.rmse_2d);
  ASSERT_TRUE(good.estimated_motion_scale && poor.estimated_motion_scale);
  EXPECT_LE(*good.estimated_motion_scale, 0.25);
  EXPECT_EQ(good.events.count("motion_scale_learnt"), 1u);
  EXPECT_LT(good.metrics.rmse_2d, 0.9 * good_fixed.metrics.rmse_2d);
  EXPECT_GE(*poor.estimated_motion_scale, 1.0);
  EXPECT_LE(poor.metrics.rmse_2d, 1.02 * poor_fixed.metrics.rmse_2d);
  EXPECT_FALSE(good_fixed.estimated_motion_scale.has_value());
  EXPECT_GT(good.metrics.coverage, 0.95);
  EXPECT_GT(poor.metrics.coverage, 0.95);
}

// uwb-shkf takes a per-range NLOS probability: with one anchor's ranges 0.5 m long (inside the
// gate, so the filter alone keeps them; 0.43 m RMSE against 0.07 m told), telling the
// filter they are likely NLOS (p = 0.9: R x 10) tracks better than not telling it, and p above
// p_reject drops the range and counts it.
TEST(Shkf, TakesAPerRangeNlosProbability) {
  data::Dataset ds = test::makeSquareLoop(5, 0.1, 60.0);
  for (auto& e : ds.events)
    if (auto* r = std::get_if<uwb::Range>(&e); r && r->anchor_id == 2) r->range += 0.5;
  data::Dataset told = ds, dropped = ds;
  long marked = 0;
  for (auto& e : told.events)
    if (auto* r = std::get_if<uwb::Range>(&e); r && r->anchor_id == 2) r->nlos_probability = 0.9;
  for (auto& e : dropped.events)
    if (auto* r = std::get_if<uwb::Range>(&e); r && r->anchor_id == 2) {
      r->nlos_probability = 0.99;
      ++marked;
    }
  auto rmse = [](const data::Dataset& d, const eval::RunResult& run) {
    return eval::computeMetrics(eval::associate(run.trajectory, d.ground_truth), run.trajectory,
                                d.ground_truth)
        .rmse_2d;
  };
  const double blind = rmse(ds, eval::runMethod(ds, "uwb-shkf", 1));
  const double informed = rmse(told, eval::runMethod(told, "uwb-shkf", 1));
  const auto run = eval::runMethod(dropped, "uwb-shkf", 1);
  std::printf("[ NLOS P   ] rmse_2d: not told %.3f m, p = 0.9 %.3f m, p = 0.99 (dropped) %.3f m\n",
              blind, informed, rmse(dropped, run));
  EXPECT_LT(informed, 0.8 * blind);
  const long count = run.statistics.rejected.count("nlos_probability")
                         ? run.statistics.rejected.at("nlos_probability")
                         : 0;
  EXPECT_GT(count, marked * 9 / 10);
  EXPECT_LE(count, marked);
}

// One uwb-iahckf statistic by hand. Start at (0, 0), P = diag(0.25, 0.25, 1, 1); the cubature
// points for the range to the anchor at (3, 4) are the start ± 1 m along x and y (ranges
// sqrt(20), sqrt(32), sqrt(18), sqrt(34)) and four velocity points at the start (range 5), so
// the predicted range is their mean. A range of 5.2 m is within the 0.24 m NLOS threshold (no
// robust factor). With prior_steps=0 (the paper's start) the first Sage-Husa weight d_0 = 1
// makes the anchor's bias the whole innovation; by default the start r̂ = 0 counts as 1/(1-b) =
// 33.3 steps (rounded to 33), so the weight is d_33 = (1-b)/(1-b^34) and the bias that share
// of the innovation.
TEST(PointFilters, IahckfFirstStatisticByHand) {
  const double predicted =
      (std::sqrt(20.0) + std::sqrt(32.0) + std::sqrt(18.0) + std::sqrt(34.0) + 4 * 5.0) / 8;
  const double b = 0.97;
  for (const auto& [spec, d] :
       {std::pair<std::string, double>{"uwb-iahckf:sigma=0.1,iq=0,calib=0,prior_steps=0", 1.0},
        {"uwb-iahckf:sigma=0.1,iq=0,calib=0", (1.0 - b) / (1.0 - std::pow(b, 34))}}) {
    loc::EstimatorContext ctx;
    ctx.anchors = {{1, {-3, 0, 0}}, {2, {3, 4, 0}}, {3, {3, -4, 0}}};
    ctx.initial_pose = Eigen::Vector3d(0, 0, 0);
    auto est = loc::Registry::builtin().create(spec, ctx);
    ASSERT_TRUE(est->process(rangeAt(10.0, 1, 3.0)).has_value());  // the start
    ASSERT_TRUE(est->process(rangeAt(10.0, 2, 5.2)).has_value());
    const auto& noise = est->statistics().estimated_noise.at(2);
    EXPECT_NEAR(noise.bias, d * (5.2 - predicted), 1e-9) << spec;
    EXPECT_EQ(noise.ranges, 1) << spec;
    EXPECT_EQ(est->statistics().events.count("robust_factor_inflated"), 0u) << spec;
  }
}

namespace {

// A robot that drives the square (2,2)-(5.2,2)-(5.2,5.2)-(2,5.2) at 0.4 m/s and, at each corner,
// turns 90 degrees in place over 2 s, so it sets off at right angles to the course it stopped on;
// four anchors, 10 Hz ranges each (staggered 0.02 s), noise std 0.05 m; 80 s (two laps).
data::Dataset turnInPlaceSquare(uint64_t seed) {
  data::Dataset ds;
  ds.name = "turn_in_place_square";
  ds.anchors = {{1, {0, 0, 2.0}}, {2, {8, 0, 2.2}}, {3, {8, 8, 1.8}}, {4, {0, 8, 2.0}}};
  const Eigen::Vector3d tag(0.1, 0.0, 1.0);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05);
  auto poseAt = [](double t) {
    const double u = std::fmod(t, 40.0);
    const int side = static_cast<int>(u / 10.0);
    const double s = u - 10.0 * side;  // 8 s driving, then 2 s turning
    const Eigen::Vector2d corners[4] = {{2, 2}, {5.2, 2}, {5.2, 5.2}, {2, 5.2}};
    const double heading = side * M_PI / 2.0;
    const Eigen::Vector2d dir(std::cos(heading), std::sin(heading));
    if (s < 8.0)
      return Eigen::Vector3d(corners[side].x() + 0.4 * s * dir.x(),
                             corners[side].y() + 0.4 * s * dir.y(), heading);
    const Eigen::Vector2d corner = corners[(side + 1) % 4];
    return Eigen::Vector3d(corner.x(), corner.y(), heading + (s - 8.0) / 2.0 * M_PI / 2.0);
  };
  for (int k = 0; k <= 800; ++k) {
    const double t = 0.1 * k;
    ds.ground_truth.push_back({t, poseAt(t)});
    for (size_t a = 0; a < ds.anchors.size(); ++a) {
      uwb::Range r;
      r.t = t + 0.02 * static_cast<double>(a);
      r.anchor_id = ds.anchors[a].id;
      r.range = uwb::predictRange(poseAt(r.t), tag, ds.anchors[a].position) + noise(rng);
      r.tag_on_robot = tag;
      ds.events.emplace_back(r);
    }
  }
  ds.start_time = 0.0;
  ds.end_time = 80.06;
  return ds;
}

}  // namespace

// uwb-ctrv-ekf at rest: its linearised model spreads the position along the held course only, so
// a robot that turns in place and drives off across that course had its fixes refused until the
// filter restarted (max_gated) and stood behind them meanwhile: 0.512 m at worst in the first 2 s
// of each leg here (0.25 m on multitag_room), rmse 0.101 m. Tracked at rest by a
// constant-velocity filter until its speed stands out, it follows them: 0.134 m at worst there
// (the lever arm's swing in the turn), rmse 0.062 m (uwb-kf 0.052 m; both overshoot each abrupt
// stop by about 0.2 m).
TEST(CtrvEkf, ARobotThatTurnsInPlaceAndDrivesOffIsFollowed) {
  const data::Dataset ds = turnInPlaceSquare(1);
  const auto run = eval::evaluateMethod(ds, "uwb-ctrv-ekf", 1, 1);
  double setting_off = 0.0;  // the worst error in the first 2 s of each leg after the first
  for (const auto& e : run.trajectory) {
    const auto truth = eval::interpolateGroundTruth(ds.ground_truth, e.t, 1.0);
    if (truth && e.t > 10.0 && std::fmod(e.t, 10.0) < 2.0)
      setting_off = std::max(setting_off, (e.pose.head<2>() - truth->head<2>()).norm());
  }
  std::printf("[ CTRV     ] turn in place, drive off: rmse %.3f m, worst setting off %.3f m\n",
              run.metrics.rmse_2d, setting_off);
  EXPECT_GT(run.metrics.coverage, 0.95);
  EXPECT_LT(setting_off, 0.25);
  EXPECT_LT(run.metrics.rmse_2d, 0.08);
}
