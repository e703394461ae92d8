// The sensitivity harness on the simulated PF-IBAS room (240 s) with the graph smoother and
// uwb-ekf: its conditions, and what sigma=auto / bias=auto promise there: within 1.25x of the
// true model for every noise std and every bias, on every anchor or on one of three. The
// one-anchor bias is found by the variance the biases explain (graph-uwb-odom 1.16-1.17x at
// 0.5, 1 and 3 m); the offsets alone, read from the solution without biases, missed it (19.9x,
// 39.7x, 112x). uwb-ekf learns its biases from the first 60 s of ranges alone, where a bias on
// every anchor reads as a range scale (+9 %, +18 %, -48 % at 0.5, 1, 3 m): a common bias is
// tried against the scale (uwb-ekf 3.6x, 6.4x, 196x before; 0.91x now).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "test_helpers.hpp"
#include "uwbloc/evaluation/sensitivity.hpp"

using namespace uwbloc;

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
  for (const auto& c : cells) {
    std::printf("[ SENSITIV ] %-14s %-28s defaults %.3f m, true model %.3f m (%.2f)\n",
                c.method.c_str(), c.condition.c_str(), c.rmse_defaults, c.rmse_true, c.ratio());
    ASSERT_TRUE(std::isfinite(c.rmse_defaults)) << c.condition;
    // Every std and every bias, on one anchor of three too (found by the variance the biases
    // explain; the offsets alone missed 0.5 m, at 19.9x); the NLOS spans have no true model.
    if (c.condition.rfind("every range NLOS", 0) != 0) {
      EXPECT_LE(c.rmse_defaults, 1.25 * c.rmse_true) << c.method << ", " << c.condition;
    }
  }
  const auto json = nlohmann::json::parse(eval::formatSensitivityJson(cells));
  EXPECT_EQ(json.size(), 28u);
  EXPECT_NE(eval::formatSensitivityMarkdown(cells).find("| sigma 1.00 m |"), std::string::npos);
}
