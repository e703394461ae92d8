// The sensitivity harness on the simulated PF-IBAS room (240 s) with the graph smoother and
// uwb-ekf: its conditions, and what sigma=auto / bias=auto promise there: within 1.25x of the
// true model for every noise std and for a bias on every anchor, and for a bias on one of three
// anchors within 1.25x of the true model with its biases freed. The one-anchor bias is found by
// the variance the biases explain; the offsets alone, read from the solution without biases,
// missed it (19.9x, 39.7x, 112x). A bias on every anchor alike is one bias shared by all
// (1.36-1.42x with a bias per anchor). uwb-ekf learns its biases from the first 60 s of ranges
// alone, where a bias on every anchor reads as a range scale (+9 %, +18 %, -48 % at 0.5, 1,
// 3 m): a common bias is tried against the scale (uwb-ekf 3.6x, 6.4x, 196x before; 0.91x now).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "test_helpers.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/evaluation/sensitivity.hpp"

using namespace uwbloc;

namespace {
void printCell(const eval::SensitivityCell& c) {
  std::printf("[ SENSITIV ] %-14s %-28s defaults %.3f m, true model %.3f m (%.2f)\n",
              c.method.c_str(), c.condition.c_str(), c.rmse_defaults, c.rmse_true, c.ratio());
}
}  // namespace

TEST(Sensitivity, ConditionsCoverTheIssuesList) {
  const auto c = eval::defaultConditions({1, 2, 3});
  ASSERT_EQ(c.size(), 14u);
  EXPECT_TRUE(c.front().bias.empty());
  EXPECT_EQ(c[3].bias.size(), 1u);  // 3 m on one anchor
  EXPECT_DOUBLE_EQ(c[3].bias.at(1), 3.0);
  EXPECT_EQ(c[6].bias.size(), 3u);  // 3 m on every anchor
  EXPECT_DOUBLE_EQ(c[10].sigma, 1.0);
  EXPECT_DOUBLE_EQ(c[13].nlos_span, 60.0);
}

TEST(Sensitivity, GraphDefaultsMatchTheTrueModel) {
  eval::SensitivityOptions o;
  o.scenario = std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/pfibas_room.ini";
  o.work_dir = (test::scratchDir() / "sensitivity").string();
  o.duration = 240.0;  // the issue's span (uwbloc sensitivity's default)
  o.seeds = 1;
  o.methods = {"graph-uwb-odom", "uwb-ekf"};
  const auto cells = eval::runSensitivity(o, nullptr);
  ASSERT_EQ(cells.size(), 28u);
  const auto conditions = eval::defaultConditions({1, 2, 3});
  for (const auto& c : cells) {
    printCell(c);
    ASSERT_TRUE(std::isfinite(c.rmse_defaults)) << c.condition;
    // The NLOS spans have no true model.
    if (c.condition.rfind("every range NLOS", 0) == 0) continue;
    const auto k = static_cast<size_t>(
        std::find_if(conditions.begin(), conditions.end(),
                     [&](const eval::SensitivityCondition& x) { return x.name == c.condition; }) -
        conditions.begin());
    ASSERT_LT(k, conditions.size()) << c.condition;
    if (c.method != "graph-uwb-odom" || conditions[k].bias.size() != 1) {
      EXPECT_LE(c.rmse_defaults, 1.25 * c.rmse_true) << c.method << ", " << c.condition;
      continue;
    }
    // The smoother's path is accurate enough (0.011 m with its learnt odometry model) that
    // freeing a bias costs as much on the ranges without any (0.016 m, with anchor 1's bias
    // alone freed as with all three): against that, the one-anchor bias found by the variance
    // the biases explain (the offsets alone missed 0.5 m, at 19.9x).
    const auto clean = data::loadDataset(
        o.work_dir + "/condition_" + std::to_string(k) + "/true_model/dataset.ini", "");
    std::ostringstream spec;
    spec << "graph-uwb-odom:sigma=" << conditions[k].sigma << ",bias=1";
    const double freed = eval::evaluateMethod(clean, spec.str(), 1, 1).metrics.rmse_2d;
    std::printf(
        "[ SENSITIV ] graph-uwb-odom %-28s true model with its biases freed %.3f m (%.2f)\n",
        c.condition.c_str(), freed, c.rmse_defaults / freed);
    EXPECT_LE(c.rmse_defaults, 1.25 * freed) << c.condition;
  }
  const auto json = nlohmann::json::parse(eval::formatSensitivityJson(cells));
  EXPECT_EQ(json.size(), 28u);
  EXPECT_NE(eval::formatSensitivityMarkdown(cells).find("| sigma 1.00 m |"), std::string::npos);
}

// uwb-pf learns from a 60 s batch with the odometry. A bias on one anchor of three is not what
// the trial frees first (one bias common to every anchor); the biases per anchor tried next
// stand because the ranges alone (graph-uwb over the same ranges) take them too. Measured with
// seeds 1-2: 0.037 / 0.036 m (1.03x) at 0.5 m, 0.041 / 0.036 m (1.14x) at 1 m; with the common
// bias alone 0.451 m (10.1x) and 0.880 m (19.7x).
TEST(Sensitivity, ParticleFilterFindsABiasOnOneAnchor) {
  eval::SensitivityOptions o;
  o.scenario = std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/pfibas_room.ini";
  o.work_dir = (test::scratchDir() / "sensitivity_pf").string();
  o.seeds = 1;
  o.methods = {"uwb-pf"};
  o.conditions = {"bias 0.5 m on anchor 1", "bias 1.0 m on anchor 1"};
  const auto cells = eval::runSensitivity(o, nullptr);
  ASSERT_EQ(cells.size(), 2u);
  for (const auto& c : cells) {
    printCell(c);
    EXPECT_LE(c.rmse_defaults, 1.25 * c.rmse_true) << c.condition;
  }
}

TEST(Sensitivity, AConditionThatIsNotOneIsAnError) {
  eval::SensitivityOptions o;
  o.scenario = std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/pfibas_room.ini";
  o.work_dir = (test::scratchDir() / "sensitivity_none").string();
  o.conditions = {"bias 2 m on anchor 1"};
  try {
    eval::runSensitivity(o, nullptr);
    FAIL() << "an unknown condition ran";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'bias 2 m on anchor 1'"), std::string::npos) << what;
    EXPECT_NE(what.find("'bias 1.0 m on anchor 1'"), std::string::npos) << what;
  }
  EXPECT_FALSE(std::filesystem::exists(o.work_dir));  // refused before anything was simulated
}
