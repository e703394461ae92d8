// `uwbloc evaluate` and `uwbloc sweep` end to end, against `compare` on the MRPT demo.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "test_helpers.hpp"

namespace fs = std::filesystem;
using Json = nlohmann::json;

namespace {

struct Result {
  int code = 0;
  std::string output;
};

Result sh(const std::string& cmd) {
  Result r;
  FILE* pipe = popen((cmd + " 2>&1").c_str(), "r");
  std::array<char, 1024> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) r.output += buf.data();
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

Result cli(const std::string& args) { return sh(std::string(UWBLOC_BINARY) + " " + args); }

Json readJson(const fs::path& p) {
  std::ifstream in(p);
  return Json::parse(in);
}

const Json& method(const Json& metrics, const std::string& name) {
  for (const auto& m : metrics["methods"])
    if (m["name"] == name) return m;
  static const Json none;
  ADD_FAILURE() << "no method " << name;
  return none;
}

const std::string kDemo = std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini";

// The table without its timing columns (ms/step, xRT), which differ from run to run.
std::string withoutTimings(const std::string& table) {
  std::istringstream in(table);
  std::string out;
  const std::regex timing(R"(\s+[-0-9.]+\s+[-0-9.]+(\s+\d+)$)");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("Wall time", 0) == 0 || line.rfind("Run directory", 0) == 0) continue;
    out += std::regex_replace(line, timing, " T T$1") + "\n";
  }
  return out;
}

}  // namespace

TEST(Evaluate, ScoresCompareOutputsAsCompareDoes) {
  const auto dir = uwbloc::test::scratchDir() / "evaluate";
  const auto r =
      cli("compare -d " + kDemo + " --methods uwb-ekf,odom,pf-ibas:n=150 --no-plots -o " +
          (dir / "run").string());
  ASSERT_EQ(r.code, 0) << r.output;
  const Json compare = readJson(dir / "run" / "metrics.json");
  const auto e =
      cli("evaluate --reference " + kDemo + " --estimate " +
          (dir / "run" / "uwb-ekf.tum").string() + " " + (dir / "run" / "odom.tum").string() + " " +
          (dir / "run" / "pf-ibas_n-150.tum").string() + " -o " + (dir / "eval").string());
  ASSERT_EQ(e.code, 0) << e.output;
  const Json ours = readJson(dir / "eval" / "metrics.json");
  for (auto [file, name] : {std::pair{"uwb-ekf", "uwb-ekf"}, std::pair{"odom", "odom"},
                            std::pair{"pf-ibas_n-150", "pf-ibas:n=150"}}) {
    // TUM keeps 6 decimals: the same figures to about a micrometre.
    for (const char* key : {"rmse_2d", "max_2d", "rmse_2d_aligned", "rpe_trans_rmse"})
      EXPECT_NEAR(method(ours, file)[key].get<double>(), method(compare, name)[key].get<double>(),
                  2e-6)
          << file << " " << key;
    EXPECT_EQ(method(ours, file)["coverage"], method(compare, name)["coverage"]);
  }
  // pf-ibas observes heading: its yaw RMSE is scored from the TUM quaternions.
  EXPECT_NEAR(method(ours, "pf-ibas_n-150")["rmse_yaw_deg"].get<double>(),
              method(compare, "pf-ibas:n=150")["rmse_yaw_deg"].get<double>(), 1e-3);
  // The same table, plots and a report come with it, and evo's statistics in ape.json.
  EXPECT_TRUE(fs::exists(dir / "eval" / "plots" / "trajectories.png"));
  EXPECT_TRUE(fs::exists(dir / "eval" / "report.html"));
  const Json ape = readJson(dir / "eval" / "ape.json");
  EXPECT_NEAR(ape["uwb-ekf"]["ape"]["rmse"].get<double>(),
              method(compare, "uwb-ekf")["rmse_2d"].get<double>(), 2e-6);
  EXPECT_NE(e.output.find("rmse_2d"), std::string::npos);
}

TEST(Evaluate, ATrajectoryFileAsReferenceAndBadInput) {
  const auto dir = uwbloc::test::scratchDir() / "evaluate_files";
  fs::create_directories(dir);
  // Reference: a straight line in "t x y phi"; estimate: the same moved by 1 m in x (TUM).
  std::ofstream ref(dir / "ref.txt"), est(dir / "est.tum");
  for (int k = 0; k <= 40; ++k) {
    ref << 0.5 * k << " " << 0.2 * k << " 0 0\n";
    // Heading 0.1 rad, which a reference without heading cannot judge.
    est << 0.5 * k << " " << 0.2 * k + 1.0 << " 0 0 0 0 0.04997917 0.99875026\n";
  }
  ref.close();
  est.close();
  const auto r =
      cli("evaluate -r " + (dir / "ref.txt").string() + " -e " + (dir / "est.tum").string() +
          " --association nearest --no-plots -o " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.output;
  const Json m = readJson(dir / "out" / "metrics.json")["methods"][0];
  EXPECT_NEAR(m["rmse_2d"].get<double>(), 1.0, 1e-9);
  EXPECT_NEAR(m["rmse_2d_aligned"].get<double>(), 0.0, 1e-9);
  EXPECT_NEAR(m["rpe_trans_rmse"].get<double>(), 0.0, 1e-9);
  EXPECT_FALSE(fs::exists(dir / "out" / "plots"));
  // A reference whose every heading is 0 has none: no heading is scored against it.
  EXPECT_TRUE(m["rmse_yaw_deg"].is_null());
  EXPECT_EQ(readJson(dir / "out" / "ape.json")["est"]["yaw_deg"]["n"], 0);
  // A file of neither layout, and a reference that never overlaps.
  std::ofstream(dir / "bad.txt") << "1 2 3\n";
  const auto bad = cli("evaluate -r " + (dir / "ref.txt").string() + " -e " +
                       (dir / "bad.txt").string() + " -o " + (dir / "bad").string());
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.output.find("bad.txt"), std::string::npos) << bad.output;
  std::ofstream(dir / "late.tum") << "1000 0 0 0 0 0 0 1\n1001 0 0 0 0 0 0 1\n";
  const auto late = cli("evaluate -r " + (dir / "ref.txt").string() + " -e " +
                        (dir / "late.tum").string() + " --no-plots -o " + (dir / "late").string());
  EXPECT_EQ(late.code, 3) << late.output;
  EXPECT_NE(late.output.find("no pose overlaps"), std::string::npos) << late.output;
}

TEST(Jobs, FewerThreadsWhenTheLargestRunsTogetherExceedTheMemoryLimit) {
  const auto dir = uwbloc::test::scratchDir() / "jobs_memory";
  // Each run is estimated at about 19 MB (200 000 starting particles x 96 B): one fits in
  // 30 MB, two do not. (The particles shrink to 50 once converged, so the runs are quick.)
  const std::string methods = " --methods uwb-pf:init_n=200000,n=50,uwb-pf:init_n=200001,n=50";
  const auto r = cli("compare -d " + kDemo + methods + " --jobs 2 --max-memory 30M --no-plots -o " +
                     (dir / "run").string());
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("Running 1 at a time instead of 2"), std::string::npos) << r.output;
  EXPECT_EQ(readJson(dir / "run" / "metrics.json")["jobs"], 1);
  const auto fits = cli("compare -d " + kDemo + methods +
                        " --jobs 2 --max-memory 60M --no-plots -o " + (dir / "run2").string());
  EXPECT_EQ(fits.output.find("at a time instead"), std::string::npos) << fits.output;
  EXPECT_EQ(readJson(dir / "run2" / "metrics.json")["jobs"], 2);
}

TEST(Sweep, PlannedJobsMergedGiveTheTableOfOneCompare) {
  const auto dir = uwbloc::test::scratchDir() / "sweep";
  const std::string methods = "uwb-ekf,pf-ibas:n=150,init_n=300,odom";  // a spec of two keys
  const auto one = cli("compare -d " + kDemo + " --methods " + methods +
                       " --repeat 2 --seed 3 --jobs 2 --no-plots -o " + (dir / "one").string());
  ASSERT_EQ(one.code, 0) << one.output;
  const auto plan = cli("sweep plan --datasets " + kDemo + " --methods " + methods +
                        " --seeds 2 --seed 3 -o " + (dir / "jobs").string());
  ASSERT_EQ(plan.code, 0) << plan.output;
  std::ofstream(dir / "jobs.txt") << plan.output;
  EXPECT_EQ(std::count(plan.output.begin(), plan.output.end(), '\n'), 6);
  // GNU parallel when it is there (the README's form), else xargs.
  const bool gnu = sh("parallel --version").code == 0;
  const auto ran = sh(gnu ? "parallel -j 2 < " + (dir / "jobs.txt").string()
                          : "xargs -P 2 -I{} sh -c {} < " + (dir / "jobs.txt").string());
  ASSERT_EQ(ran.code, 0) << ran.output;
  const auto merged =
      cli("sweep merge " + (dir / "jobs").string() + " -o " + (dir / "merged").string());
  ASSERT_EQ(merged.code, 0) << merged.output;
  std::ifstream a(dir / "one" / "report.txt"), b(dir / "merged" / "mrpt_uwb_demo" / "report.txt");
  const std::string ta((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
  const std::string tb((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
  ASSERT_FALSE(ta.empty());
  EXPECT_EQ(withoutTimings(ta), withoutTimings(tb));
  // And the JSON figures, bit for bit.
  const Json ja = readJson(dir / "one" / "metrics.json");
  const Json jb = readJson(dir / "merged" / "mrpt_uwb_demo" / "metrics.json");
  ASSERT_EQ(ja["methods"].size(), jb["methods"].size());
  for (size_t i = 0; i < ja["methods"].size(); ++i)
    for (const char* key : {"name", "runs", "rmse_2d", "rmse_2d_std", "rmse_2d_worst", "max_2d",
                            "rmse_2d_aligned", "rpe_trans_rmse", "seed_runs", "cdf", "rejected"})
      EXPECT_EQ(ja["methods"][i][key], jb["methods"][i][key]) << i << " " << key;
  // A metrics.json that is not one of ours is named with the field it lacks.
  fs::create_directories(dir / "bad");
  std::ofstream(dir / "bad" / "metrics.json") << R"({"dataset": "x", "methods": [{"name": "a"}]})";
  const auto bad = cli("sweep merge " + (dir / "bad").string() + " -o " + (dir / "m2").string());
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.output.find((dir / "bad" / "metrics.json").string()), std::string::npos)
      << bad.output;
  EXPECT_NE(bad.output.find("\"runs\""), std::string::npos) << bad.output;
  // A typo in the plan fails at once, naming the file.
  const auto typo =
      cli("sweep plan --datasets nowhere.ini --methods odom -o " + (dir / "x").string());
  EXPECT_NE(typo.code, 0);
  EXPECT_NE(typo.output.find("nowhere.ini"), std::string::npos) << typo.output;
}
