// Every committed scenario runs through every registered method; the greenhouse scenarios are
// printed beside the greenhouse paper's Table 1; a CARMEN log is imported and augmented.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>

#include "simulated_scenario.hpp"
#include "test_helpers.hpp"
#include "uwbloc/dataset/carmen_import.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/benchmark.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

using namespace uwbloc;

class EveryScenario : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryScenario, RunsThroughEveryMethod) {
  const auto ds = test::simulatedScenario(GetParam(), 1);
  std::vector<eval::MethodSummary> all;
  for (const auto& m : loc::Registry::builtin().names()) {
    if (!eval::missingNeeds(ds, m).empty()) continue;  // e.g. LiDAR methods in an open field
    all.push_back(eval::evaluateMethod(ds, m, 1, 1));
    // Every method that runs covers the scenario, and never produced a non-finite estimate
    // (the guard in Estimator::process() counts one as non_finite_estimate before dropping it).
    EXPECT_GT(all.back().metrics.coverage, 0.9) << GetParam() << " " << m;
    EXPECT_EQ(all.back().rejected.count("non_finite_estimate"), 0u) << GetParam() << " " << m;
  }
  std::printf("%s", eval::formatTable(ds, all, eval::computeBounds(ds)).c_str());
}

INSTANTIATE_TEST_SUITE_P(Committed, EveryScenario,
                         ::testing::Values("pfibas_room", "greenhouse_r1", "greenhouse_r2",
                                           "greenhouse_r3", "agv_room", "plate", "corridor",
                                           "static_los", "tracking_los", "office"));

// The simulated office: the inner wall hides one room's anchors from the other, and 42 % of the
// ranges read long by an exponential excess (mean 0.6 m). Under the robust loss the smoothers read
// the excess as noise about longer distances and push the path away from the hidden anchors
// (graph-uwb-odom 0.200 m, graph-uwb 0.244 m, seed 1); under the NLOS mixture learnt from their
// own residuals the short ranges place it (0.075 m, 0.091 m). graph-uwb-odom's odometry model
// is then learnt by cross-validation on the held-out ranges' LOS part: 1/4 and 0.044 m (the
// spread of every range, NLOS excess and all, kept it at 1, 0.055 m, level with the odometry
// alone, 0.054 m).
TEST(Office, SmoothersTakeTheNlosMixture) {
  const auto ds = test::simulatedScenario("office", 1);
  for (const std::string m : {"graph-uwb-odom", "graph-uwb"}) {
    const auto state = eval::evaluateMethod(ds, m, 1, 1);
    const auto mixture = eval::evaluateMethod(ds, m + ":nlos_state=0", 1, 1);
    const auto robust = eval::evaluateMethod(ds, m + ":nlos_mixture=0", 1, 1);
    std::printf(
        "[ OFFICE   ] %s rmse_2d %.3f m (nlos_state=0: %.3f m, nlos_mixture=0: %.3f m), "
        "NLOS state over %.3g s\n",
        m.c_str(), state.metrics.rmse_2d, mixture.metrics.rmse_2d, robust.metrics.rmse_2d,
        state.estimated_nlos_memory.value_or(0.0));
    EXPECT_GT(mixture.events.count("range_mixture_solves"), 0u) << m;
    EXPECT_EQ(robust.events.count("range_mixture_solves"), 0u) << m;
    EXPECT_EQ(mixture.events.count("nlos_state_solves"), 0u) << m;
    EXPECT_GT(state.events.count("nlos_state_solves"), 0u) << m;
    EXPECT_LT(mixture.metrics.rmse_2d, 0.5 * robust.metrics.rmse_2d) << m;
    EXPECT_LT(mixture.metrics.rmse_2d, m == "graph-uwb" ? 0.12 : 0.1) << m;
    EXPECT_LT(state.metrics.rmse_2d, 0.85 * mixture.metrics.rmse_2d) << m;
    if (m == "graph-uwb-odom") {
      std::printf("[ OFFICE   ] %s odometry noise x%.4g\n", m.c_str(),
                  state.estimated_motion_scale.value_or(1.0));
      EXPECT_LT(state.estimated_motion_scale.value_or(1.0), 1.0);
      EXPECT_LT(state.metrics.rmse_2d, 0.05);
    }
  }
}

TEST(Greenhouse, TableBesideThePaper) {
  // The paper's Table 1, MAE [m] for R1/R2/R3 (UWB, KF, AKF, IAKF); AKF and IAKF are not built yet.
  const double paper_uwb[3] = {0.381, 0.487, 0.672}, paper_kf[3] = {0.211, 0.383, 0.631};
  const double sigma[3] = {0.1, 0.5, 1.0};
  std::printf("[ GREENHSE ] MAE [m] over 5 simulated seeds      ours          paper\n");
  for (int level = 0; level < 3; ++level) {
    double uwb = 0.0, kf = 0.0;
    const int seeds = 5;
    for (int seed = 1; seed <= seeds; ++seed) {
      const auto ds = test::simulatedScenario("greenhouse_r" + std::to_string(level + 1),
                                              static_cast<uint64_t>(seed));
      uwb += eval::evaluateMethod(ds, "uwb-ls", 1, 1).metrics.mae_2d / seeds;
      const std::string kf_spec = "uwb-kf:solver=ls,sigma=" + std::to_string(sigma[level]);
      kf += eval::evaluateMethod(ds, kf_spec, 1, 1).metrics.mae_2d / seeds;
    }
    std::printf("[ GREENHSE ] R%d  UWB (uwb-ls)                    %.3f         %.3f\n", level + 1,
                uwb, paper_uwb[level]);
    std::printf("[ GREENHSE ] R%d  KF  (uwb-kf:solver=ls,sigma=%.1f) %.3f         %.3f\n",
                level + 1, sigma[level], kf, paper_kf[level]);
    EXPECT_LT(kf, uwb) << "R" << level + 1;  // the paper's finding: filtering lowers the MAE
  }
}

TEST(Augment, PosesBetweenTheReferencesFollowTheOdometry) {
  // The robot drives a circle of radius 2 m around an anchor at the tag's height, at 0.5 rad/s;
  // the reference has a pose every 2 s, the odometry (exact) comes at 10 Hz from t = 0 (its first
  // increment, at rest, starts the track). Every simulated
  // range then measures 2 m. On the chords between the reference poses it would measure down
  // to r cos(w T / 2) = 1.08 m... 1.76 m.
  const double r = 2.0, w = 0.5;
  const auto on = [&](double t) {
    return Eigen::Vector3d(r * std::cos(w * t), r * std::sin(w * t), w * t + M_PI / 2.0);
  };
  std::vector<data::TimedPose> reference;
  for (double t = 0.0; t <= 20.0 + 1e-9; t += 2.0) reference.push_back({t, on(t)});
  std::vector<loc::Event> odometry;
  for (int k = 0; k <= 200; ++k) {
    loc::OdometryIncrement inc;
    inc.t = 0.1 * k;
    inc.delta = loc::relativePose(on(0.1 * std::max(k - 1, 0)), on(inc.t));
    odometry.emplace_back(inc);
  }
  data::UwbSimSpec uwb;
  uwb.sigma = 0.0;
  const std::vector<uwb::Anchor> anchors{{1, {0.0, 0.0, 1.0}}};
  const auto truthOf = [&](const std::vector<loc::Event>& events, data::PathBetweenPoses& path) {
    std::vector<data::RangeTruth> truth;
    data::augmentWithUwb(events, reference, anchors, uwb, nullptr, 1, &truth, 5.0, true, &path);
    return truth;
  };
  data::PathBetweenPoses along(odometry);
  const auto shaped = truthOf(odometry, along);
  ASSERT_GT(shaped.size(), 150u);
  for (const auto& x : shaped) EXPECT_NEAR(x.true_range, r, 1e-6) << x.t;
  EXPECT_EQ(along.straight(), 0);
  EXPECT_EQ(along.odometryShaped(), static_cast<long>(shaped.size()));
  // Without odometry, or with odometry that misses the next reference pose (here twice as long
  // as the motion), the poses lie on the chords.
  const auto shortest = [](const std::vector<data::RangeTruth>& truth) {
    double m = 1e9;
    for (const auto& x : truth) m = std::min(m, x.true_range);
    return m;
  };
  data::PathBetweenPoses none({});
  EXPECT_NEAR(shortest(truthOf({}, none)), r * std::cos(0.5), 0.01);
  EXPECT_EQ(none.odometryShaped(), 0);
  auto doubled = odometry;
  for (auto& e : doubled) std::get<loc::OdometryIncrement>(e).delta *= 2.0;
  data::PathBetweenPoses wrong(doubled);
  EXPECT_NEAR(shortest(truthOf(doubled, wrong)), r * std::cos(0.5), 0.01);
  EXPECT_EQ(wrong.odometryShaped(), 0);
}

TEST(Carmen, ImportAndAugmentIntel) {
  const auto log = test::sharedData("carmen_2d_laser/intel-corrected.log.gz");
  UWBLOC_REQUIRE_SHARED_DATA(log);
  const auto dir = test::scratchDir();
  const auto imported = data::importCarmen(log.string(), (dir / "intel").string());
  EXPECT_EQ(imported.scans, 910);  // scans
  EXPECT_EQ(imported.ground_truth_rows, 910);
  // Anchors inside the building, on the reference path.
  test::writeText(dir / "anchors.csv",
                  "id,x,y,z\n1,0.60,-0.03,2.5\n2,-6.72,0.06,2.5\n3,16.32,-13.53,2.5\n"
                  "4,-6.85,-16.98,2.5\n5,10.23,-19.09,2.5\n6,-1.35,-5.10,2.5\n");
  data::AugmentRequest req;
  req.rawlog = (dir / "intel" / "carmen.rawlog").string();
  req.reference = (dir / "intel" / "reference.txt").string();
  req.anchors_csv = (dir / "anchors.csv").string();
  req.map = "scans";
  const auto manifest = data::writeAugmented(req, (dir / "aug").string());
  const auto ds = data::loadDataset(manifest, "");
  long ranges = 0, scans = 0;
  for (const auto& e : ds.events) {
    ranges += std::holds_alternative<uwb::Range>(e);
    scans += std::holds_alternative<loc::LaserScan>(e);
  }
  EXPECT_EQ(scans, 910);
  EXPECT_GT(ranges, 100000);
  const auto gn = eval::evaluateMethod(ds, "uwb-gn", 1, 1);
  std::printf(
      "[ CARMEN   ] intel + 6 simulated anchors: %ld ranges, uwb-gn rmse %.3f m, coverage %.2f\n",
      ranges, gn.metrics.rmse_2d, gn.metrics.coverage);
  EXPECT_GT(gn.metrics.coverage, 0.9);
  EXPECT_LT(gn.metrics.rmse_2d, 1.0);
  // uwb-iahckf's Sage-Husa bias per anchor, unbounded, follows the filter's own position error
  // through these NLOS ranges (the learning start has already removed a constant bias): within
  // twice the range sigma (bias_max=auto) it tracks far better.
  const auto iah = eval::evaluateMethod(ds, "uwb-iahckf", 1, 1);
  const auto unbounded = eval::evaluateMethod(ds, "uwb-iahckf:bias_max=1000", 1, 1);
  std::printf("[ CARMEN   ] intel + 6 simulated anchors: uwb-iahckf %.3f m (%.3f m unbounded)\n",
              iah.metrics.rmse_2d, unbounded.metrics.rmse_2d);
  EXPECT_GE(iah.events.count("bias_at_bias_max"), 1u);
  EXPECT_LT(iah.metrics.rmse_2d, 0.75 * unbounded.metrics.rmse_2d);
  // 83 % of these ranges are NLOS, each long by an exponential excess: the particle filters'
  // learning start finds the LOS / NLOS mixture and takes it as the range likelihood. fused-pf
  // learns it at lidar-mcl's pose over the first 120 s (80 % NLOS, +0.42 m), and tracks each
  // anchor's NLOS state through it: 0.084 m, against 0.124 m with the mixture's one NLOS share
  // for every range (nlos_memory=0), where an anchor in sight all along reads as 80 % NLOS;
  // lidar-mcl 0.105 m. (Before the particle filters skipped the odometry recorded before the
  // start pose: 0.116 m, lidar-mcl 0.123 m.)
  const auto fused = eval::evaluateMethod(ds, "fused-pf", 1, 1);
  const auto untracked = eval::evaluateMethod(ds, "fused-pf:nlos_memory=0", 1, 1);
  std::printf(
      "[ CARMEN   ] intel + 6 simulated anchors: fused-pf rmse %.3f m (%.3f m with one NLOS "
      "share for every range)\n",
      fused.metrics.rmse_2d, untracked.metrics.rmse_2d);
  EXPECT_EQ(fused.events.count("range_mixture_in_force"), 1u);
  EXPECT_EQ(fused.events.count("range_mixture_at_lidar_pose"), 1u);
  ASSERT_TRUE(fused.estimated_range_mixture);
  EXPECT_GT(fused.estimated_range_mixture->nlos_fraction, 0.6);
  EXPECT_GT(fused.metrics.coverage, 0.9);
  EXPECT_LT(fused.metrics.rmse_2d, 0.2);
  EXPECT_LT(fused.metrics.rmse_2d, 0.8 * untracked.metrics.rmse_2d);
  // The ranges' errors persist over several ranges: each range counts for 1 / their
  // autocorrelation time (0.394 here), and fusion is no worse than the LiDAR alone (issue 12's
  // 1.05).
  const auto lidar = eval::evaluateMethod(ds, "lidar-mcl", 1, 1);
  std::printf(
      "[ CARMEN   ] intel + 6 simulated anchors: each range counted %.3f; lidar-mcl %.3f m\n",
      fused.estimated_range_mixture->weight, lidar.metrics.rmse_2d);
  EXPECT_LT(fused.estimated_range_mixture->weight, 0.5);
  EXPECT_LE(fused.metrics.rmse_2d, 1.05 * lidar.metrics.rmse_2d);
  // PF-IBAS (40 particles, more while the cloud is spread): no worse than the LiDAR alone
  // either, and, like fused-pf, better for tracking each anchor's NLOS state (0.068 against
  // 0.088 m; with a fixed 40 particles 0.082 against 0.120 m).
  const auto ibas = eval::evaluateMethod(ds, "pf-ibas", 1, 1);
  const auto ibas_untracked = eval::evaluateMethod(ds, "pf-ibas:nlos_memory=0", 1, 1);
  std::printf(
      "[ CARMEN   ] intel + 6 simulated anchors: pf-ibas %.3f m (%.3f m with one NLOS share)\n",
      ibas.metrics.rmse_2d, ibas_untracked.metrics.rmse_2d);
  EXPECT_LE(ibas.metrics.rmse_2d, 1.05 * lidar.metrics.rmse_2d);
  EXPECT_LT(ibas.metrics.rmse_2d, 0.8 * ibas_untracked.metrics.rmse_2d);
}

// Issue 12's rule on the benchmark's aces+uwb (6 anchors on the reference path, NLOS where the
// tag-anchor segment crosses the map of the log's scans): over 5 seeds pf-ibas's worst seed is
// at most 1.05 x the LiDAR alone's mean. The count from KLD-sampling is what holds it: 0.074 /
// 0.078 m against lidar-mcl's 0.084 m; with the fixed 40 particles (n_max=0) 0.091 / 0.108 m,
// 1.29 x, its error peaking at 0.9 m on seed 5 where the cloud spreads to 0.46 m.
TEST(Carmen, AcesWithUwbPfIbasWorstSeedWithinTheLidarAlone) {
  const auto log = test::sharedData("carmen_2d_laser/aces-corrected.log.gz");
  UWBLOC_REQUIRE_SHARED_DATA(log);
  eval::BenchmarkOptions o;
  o.data_dir = data::resolveDataDir();
  o.project_datasets = std::string(UWBLOC_SOURCE_DIR) + "/datasets";
  o.work_dir = test::scratchDir().string();
  o.seeds = 5;
  o.methods = {"lidar-mcl", "pf-ibas", "pf-ibas:n_max=0"};
  o.datasets = {"carmen/aces+uwb"};
  const auto datasets = eval::prepareBenchmarkDatasets(o, [](const std::string&) {});
  ASSERT_EQ(datasets.size(), 1u);
  const auto cells = eval::runBenchmark(datasets, o, [](const std::string&) {});
  std::map<std::string, eval::BenchmarkCell> by;
  for (const auto& c : cells) by[c.method] = c;
  ASSERT_EQ(by.size(), 3u);
  for (const auto& [method, c] : by)
    std::printf("[ CARMEN   ] aces + 6 simulated anchors, 5 seeds: %s %.3f / %.3f m\n",
                method.c_str(), c.mean_rmse, c.worst_rmse);
  const double lidar = by["lidar-mcl"].mean_rmse;
  EXPECT_GT(by["pf-ibas"].coverage, 0.9);
  EXPECT_LE(by["pf-ibas"].worst_rmse, 1.05 * lidar);
  EXPECT_LT(by["pf-ibas"].worst_rmse, 0.85 * by["pf-ibas:n_max=0"].worst_rmse);
}

TEST(Benchmark, TableOfMeanAndWorstSeedOverDatasets) {
  eval::BenchmarkOptions o;
  o.project_datasets = std::string(UWBLOC_SOURCE_DIR) + "/datasets";
  o.work_dir = test::scratchDir().string();
  o.seeds = 3;
  o.methods = {"uwb-gn", "uwb-ekf", "lidar-mcl"};
  o.datasets = {"sim/static_los", "sim/pfibas_room"};
  std::vector<std::string> lines;
  const auto log = [&](const std::string& l) { lines.push_back(l); };
  const auto datasets = eval::prepareBenchmarkDatasets(o, log);
  ASSERT_EQ(datasets.size(), 2u);
  const auto cells = eval::runBenchmark(datasets, o, log);
  // static_los has no LiDAR: lidar-mcl does not run there.
  ASSERT_EQ(cells.size(), 5u);
  for (const auto& c : cells) {
    EXPECT_LE(c.mean_rmse, c.worst_rmse + 1e-12) << c.dataset << " " << c.method;
    EXPECT_GT(c.coverage, 0.9) << c.dataset << " " << c.method;
    EXPECT_TRUE(c.flag.empty()) << c.flag;
  }
  for (const auto& c : cells) EXPECT_EQ(c.coverage_max, 1.0) << c.dataset;
  const std::string md = eval::formatBenchmarkMarkdown(cells, 3);
  EXPECT_NE(md.find("| method | sim/pfibas_room | sim/static_los |"), std::string::npos) << md;
  EXPECT_NE(md.find("| lidar-mcl |"), std::string::npos) << md;
  const std::string json = eval::formatBenchmarkJson(cells, 3);
  EXPECT_NE(json.find("\"rmse_2d_worst\""), std::string::npos);
  // A parameter the method does not take, or no such method, is an error before any run, not
  // a column of empty cells.
  o.methods = {"uwb-gn", "pf-ibas+graph:carry=0"};
  test::expectErrorMentions<loc::ParamError>([&] { eval::runBenchmark(datasets, o, log); },
                                             {"pf-ibas+graph:carry=0", "carry"});
  o.methods = {"uwb-gm"};
  test::expectErrorMentions<loc::ParamError>([&] { eval::runBenchmark(datasets, o, log); },
                                             {"unknown method 'uwb-gm'", "uwb-gn"});
}

// A reference that outlasts the recording's measurements (Hanyang NLOS A1: the ranges end at
// 259 s of a 314 s reference) caps every method's coverage: measurements 0-80 s, a reference at
// 1 Hz over 0-100 s, so 82 of its 101 samples lie within 1 s of the measurements. The dataset
// says so, and the benchmark shows the cap beside the coverage instead of a bare shortfall.
TEST(Benchmark, ReferenceBeyondTheRecordingCapsTheCoverage) {
  data::Dataset ds;
  ds.manifest.ground_truth = "reference.tum";
  for (int k = 0; k <= 80; ++k) {
    uwb::Range r;
    r.t = k;
    r.anchor_id = 1;
    r.range = 5.0;
    ds.events.emplace_back(r);
  }
  ds.start_time = 0.0;
  ds.end_time = 80.0;
  for (int k = 0; k <= 100; ++k) ds.ground_truth.push_back({double(k), Eigen::Vector3d::Zero()});
  EXPECT_NEAR(data::referenceReach(ds), 82.0 / 101.0, 1e-12);
  const auto w = data::referenceBeyondRecordingWarning(ds);
  ASSERT_TRUE(w.has_value());
  for (const char* part : {"reference.tum", "0.0 s before", "20.0 s after", "19 %", "0.81 of it"})
    EXPECT_NE(w->find(part), std::string::npos) << part << " in: " << *w;
  // Within 95 %: nothing to say (5 s beyond a 100 s reference).
  ds.end_time = 95.0;
  EXPECT_FALSE(data::referenceBeyondRecordingWarning(ds).has_value());

  eval::BenchmarkCell capped{
      "hanyang/NLOS_TrajA_Case1", "defaults", "uwb-ekf", 0.844, 0.844, 0.829, 0.83, ""};
  eval::BenchmarkCell short_run = capped;
  short_run.dataset = "sim/room";
  short_run.coverage_max = 1.0;
  const std::string md = eval::formatBenchmarkMarkdown({capped, short_run}, 1);
  EXPECT_NE(md.find("0.844 / 0.844 (cov 0.83 of at most 0.83)"), std::string::npos) << md;
  EXPECT_NE(md.find("0.844 / 0.844 (cov 0.83) |"), std::string::npos) << md;
  EXPECT_NE(eval::formatBenchmarkJson({capped}, 1).find("\"coverage_max\": 0.83"),
            std::string::npos);
}

// Issue 12's rule, said where the table is read: a mean more than 3 times the best of its column
// (the same dataset and variant, among the cells with an estimate) is flagged in its cell and
// listed under the table; the manifest-facts column has its own best.
TEST(Benchmark, ACellOverThreeTimesItsColumnsBestIsFlagged) {
  const auto cell = [](const char* dataset, const char* variant, const char* method, double mean,
                       const char* flag = "") {
    return eval::BenchmarkCell{dataset, variant, method, mean, mean, 1.0, 1.0, flag};
  };
  std::vector<eval::BenchmarkCell> cells{cell("a", "defaults", "m1", 0.10),
                                         cell("a", "defaults", "m2", 0.35),
                                         cell("a", "defaults", "m3", 0.0, "no_estimate"),
                                         cell("a", "manifest facts", "m1", 0.30),
                                         cell("a", "manifest facts", "m2", 0.35),
                                         cell("b", "defaults", "m1", 0.20),
                                         cell("b", "defaults", "m2", 0.60)};
  eval::rateAgainstTheBest(cells);
  EXPECT_NEAR(cells[0].times_best, 1.0, 1e-12);
  EXPECT_NEAR(cells[1].times_best, 3.5, 1e-12);
  EXPECT_EQ(cells[2].times_best, 0.0);
  EXPECT_NEAR(cells[4].times_best, 0.35 / 0.30, 1e-12);
  EXPECT_NEAR(cells[6].times_best, 3.0, 1e-12);  // at the limit: not over it
  const std::string md = eval::formatBenchmarkMarkdown(cells, 1);
  EXPECT_NE(md.find("| 0.350 / 0.350 (**3.5x the best**) |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 0.600 / 0.600 |"), std::string::npos) << md;
  EXPECT_NE(md.find("1 cell(s) over 3 times the best of their column: m2 on a (3.5x)."),
            std::string::npos)
      << md;
  const auto json = nlohmann::json::parse(eval::formatBenchmarkJson(cells, 1));
  EXPECT_NEAR(json["cells"][1]["times_best"].get<double>(), 3.5, 1e-12);
  EXPECT_TRUE(json["cells"][2]["times_best"].is_null());
  cells.erase(cells.begin() + 1);
  EXPECT_NE(eval::formatBenchmarkMarkdown(cells, 1).find(
                "Every method is within 3 times the best of its column."),
            std::string::npos);
}
