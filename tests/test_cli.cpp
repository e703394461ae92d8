// The command line on bad input: a non-zero exit and a message naming the file (and line).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <fstream>

#include "csv_drive.hpp"
#include "test_helpers.hpp"
#include "uwbloc/dataset/rawlog.hpp"

using uwbloc::test::writeText;

namespace {

struct Result {
  int code = 0;
  std::string output;
};

Result runCli(const std::string& args) {
  const std::string cmd = std::string(UWBLOC_BINARY) + " " + args + " 2>&1";
  Result r;
  FILE* pipe = popen(cmd.c_str(), "r");
  std::array<char, 512> buf{};
  while (fgets(buf.data(), buf.size(), pipe)) r.output += buf.data();
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

void expectFailureMentioning(const Result& r, std::initializer_list<std::string> parts) {
  EXPECT_NE(r.code, 0) << r.output;
  for (const auto& p : parts) EXPECT_NE(r.output.find(p), std::string::npos) << r.output;
}

// `count` ranges of 4 m, 0.1 s apart, anchors 1-3 in turn (or the stamps `stamp(k)`), written
// as a rawlog at `path`.
template <class Stamp>
void writeRanges(const std::filesystem::path& path, int count, Stamp stamp, int anchors = 3) {
  std::vector<uwbloc::loc::Event> events;
  for (int k = 0; k < count; ++k) {
    uwbloc::uwb::Range r;
    r.t = stamp(k);
    r.anchor_id = 1 + k % anchors;
    r.range = 4.0;
    events.emplace_back(r);
  }
  uwbloc::data::writeRawlog(path.string(), events);
}
void writeRanges(const std::filesystem::path& path, int count, int anchors = 3) {
  writeRanges(
      path, count, [](int k) { return 0.1 * k; }, anchors);
}

std::string manifestFor(const std::filesystem::path& dir, const std::string& rawlog,
                        const std::string& anchors = "anchors_csv = anchors.csv") {
  writeText(dir / "anchors.csv", "id,x,y,z\n1,0,0,2\n2,6,0,2\n3,0,6,2\n");
  return writeText(dir / "m.ini",
                   "[dataset]\nrawlog = " + rawlog + "\n[anchors]\n" + anchors + "\n");
}

}  // namespace

// The README's table of limits is what `uwbloc methods --limits` prints, line for line: a limit
// added, changed or removed in the code fails here until the README says the same.
TEST(Cli, TheReadmesLimitsTableIsWhatMethodsLimitsPrints) {
  const auto printed = runCli("methods --limits");
  ASSERT_EQ(printed.code, 0) << printed.output;
  std::ifstream readme(std::string(UWBLOC_SOURCE_DIR) + "/README.md");
  ASSERT_TRUE(readme) << "README.md not found";
  const std::string header = "| parameter | range | why |";
  const std::string last = "Every other numeric parameter must be finite.";
  std::string line, table;
  bool inside = false;
  while (std::getline(readme, line)) {
    if (line == header) inside = true;
    if (!inside) continue;
    table += line + "\n";
    if (line == last) break;
  }
  ASSERT_FALSE(table.empty()) << "README.md has no line '" << header << "'";
  EXPECT_EQ(table, printed.output);
}

TEST(Cli, MissingRawlog) {
  const auto dir = uwbloc::test::scratchDir();
  const auto m = manifestFor(dir, "nowhere.rawlog");
  expectFailureMentioning(runCli("run -d " + m + " -o " + (dir / "out").string()),
                          {"error:", (dir / "nowhere.rawlog").string(), "not found"});
}

TEST(Cli, TruncatedRawlog) {
  const auto dir = uwbloc::test::scratchDir();
  std::ifstream src(uwbloc::test::kDemoRawlog, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
  std::ofstream(dir / "cut.rawlog", std::ios::binary) << bytes.substr(0, bytes.size() / 3);
  const auto m = manifestFor(dir, "cut.rawlog");
  expectFailureMentioning(runCli("run -d " + m + " -o " + (dir / "out").string()),
                          {"error:", "cut.rawlog", "rawlog"});
}

TEST(Cli, ManifestWithUnknownKeyOrNoAnchors) {
  const auto dir = uwbloc::test::scratchDir();
  const auto m = manifestFor(dir, "x.rawlog", "anchors_csv = anchors.csv\nanchor_height = 2");
  expectFailureMentioning(runCli("run -d " + m),
                          {"error:", m + ":5", "unknown key 'anchor_height'"});
  const auto none = writeText(dir / "none.ini", "[dataset]\nrawlog = x.rawlog\n");
  expectFailureMentioning(runCli("run -d " + none), {"error:", none, "no anchors"});
}

TEST(Cli, MalformedCsvRow) {
  const auto dir = uwbloc::test::scratchDir();
  const auto m = manifestFor(dir, "x.rawlog");
  writeText(dir / "anchors.csv", "id,x,y,z\n1,0,0,2\n2,6,0\n");
  expectFailureMentioning(runCli("run -d " + m),
                          {"error:", (dir / "anchors.csv").string() + ":3", "expected 4 fields"});
}

TEST(Cli, UnknownMethodAndParameter) {
  const auto dir = uwbloc::test::scratchDir();
  expectFailureMentioning(runCli("run -m uwb-magic -o " + (dir / "o").string()),
                          {"error:", "unknown method 'uwb-magic'"});
  expectFailureMentioning(runCli("compare -m uwb-kf:qq=2 -o " + (dir / "o").string()),
                          {"error:", "unknown parameter(s) qq"});
}

TEST(Cli, HelpAndMethodList) {
  const auto help = runCli("compare --help");
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.output.find("--repeat"), std::string::npos);
  const auto list = runCli("methods");
  EXPECT_EQ(list.code, 0);
  for (const char* m : {"uwb-ls", "uwb-gn", "uwb-chan", "uwb-kf", "uwb-ekf", "odom"})
    EXPECT_NE(list.output.find(m), std::string::npos) << m;
}

TEST(Cli, CompareWritesTheRunDirectory) {
  const auto dir = uwbloc::test::scratchDir();
  const auto r = runCli("compare -m uwb-ekf,uwb-kf:q=0.2,sigma=0.2 -o " + (dir / "run").string());
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* f : {"metrics.json", "metrics.csv", "config.ini", "report.txt", "uwb-ekf.tum",
                        "uwb-kf_q-0.2_sigma-0.2.tum"})
    EXPECT_TRUE(std::filesystem::exists(dir / "run" / f)) << f;
  std::ifstream json(dir / "run" / "metrics.json");
  const std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  for (const char* key : {"\"dataset\"", "\"duration_s\"", "\"rmse_2d_std\"", "\"realtime_factor\"",
                          "\"rejected\"", "\"coverage\""})
    EXPECT_NE(text.find(key), std::string::npos) << key;
}

// The benchmark writes its tables into a folder that does not exist yet, even when no dataset
// needed importing there (the MRPT demo alone: it failed with "cannot write file" before).
TEST(Cli, BenchmarkCreatesItsFolder) {
  const auto dir = uwbloc::test::scratchDir();
  std::filesystem::create_directories(dir / "empty");
  const auto out = dir / "new" / "bench";
  const auto r = runCli("benchmark --data-dir " + (dir / "empty").string() +
                        " --datasets mrpt_demo -m uwb-ls --seeds 1 -o " + out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(out / "benchmark.md"));
  EXPECT_TRUE(std::filesystem::exists(out / "benchmark.json"));
}

// The import loads what it wrote and prints what loading says: a reference in another frame
// than the anchors is reported at the first look at one's data, with the manifest line.
TEST(Cli, ImportPrintsWhatLoadingTheDatasetSays) {
  const auto dir = uwbloc::test::scratchDir();
  const auto [ranges, ref] =
      uwbloc::test::driveACircle({0.0, 0.0, 0.8}, {2.0, -1.5, 25.0 * M_PI / 180.0});
  const auto r =
      runCli("import csv --ranges " + writeText(dir / "r.csv", ranges) + " --anchors " +
             writeText(dir / "a.csv", uwbloc::test::kFourAnchors) + " --reference " +
             writeText(dir / "ref.csv", ref) + " --tag 0,0,0,0.8 --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("WARNING: "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("gt_origin_in_anchor_frame = "), std::string::npos) << r.output;
}

TEST(Cli, CollapsedTimestampsAreRefusedUnlessAllowed) {
  // 300 ranges written with six significant digits: two distinct stamps.
  const auto dir = uwbloc::test::scratchDir();
  writeRanges(dir / "c.rawlog", 300, [](int k) { return k < 150 ? 1.13486e9 : 1.13487e9; });
  const auto manifest = manifestFor(dir, "c.rawlog");
  const auto out = (dir / "run").string();
  expectFailureMentioning(
      runCli("compare -d " + manifest + " -m uwb-ls -o " + out),
      {"c.rawlog", "collapsed", "2 distinct stamps for 300 messages", "--allow-bad-time"});
  const auto allowed =
      runCli("compare -d " + manifest + " -m uwb-ls -o " + out + " --allow-bad-time");
  EXPECT_EQ(allowed.code, 0) << allowed.output;
  EXPECT_NE(allowed.output.find("WARNING"), std::string::npos) << allowed.output;
}

TEST(Cli, AMethodWithoutAnEstimateIsFlaggedAndStrictExitsThree) {
  // Ranges from one anchor only: no epoch can be solved.
  const auto dir = uwbloc::test::scratchDir();
  writeRanges(dir / "one.rawlog", 100, 1);
  const auto manifest = manifestFor(dir, "one.rawlog");
  const auto out = (dir / "run").string();
  // No method produced a result: never a success, --strict or not.
  const auto none = runCli("compare -d " + manifest + " -m uwb-ls -o " + out);
  EXPECT_EQ(none.code, 3) << none.output;
  EXPECT_NE(none.output.find("FLAGGED: uwb-ls produced no estimate"), std::string::npos)
      << none.output;
  // One method without a result beside one with: flagged; an error only with --strict. Three
  // anchors, all ranges 4 m: uwb-ls solves every epoch, uwb-ekf never accepts a start fix (with
  // no biases learnt: biases of -0.19, -0.71, -0.71 m would make those ranges agree).
  writeRanges(dir / "three.rawlog", 100);
  const auto three = manifestFor(dir, "three.rawlog");
  const std::string both =
      "compare -d " + three + " -m uwb-ls,uwb-ekf:init_residual=0.01,calib_bias=0 -o " + out;
  const auto lenient = runCli(both);
  EXPECT_EQ(lenient.code, 0) << lenient.output;
  EXPECT_NE(lenient.output.find("FLAGGED: uwb-ekf"), std::string::npos) << lenient.output;
  EXPECT_EQ(runCli(both + " --strict").code, 3);
}

TEST(Cli, RunDirectoryIsReplacedWholeAndLocked) {
  const auto dir = uwbloc::test::scratchDir();
  const auto out = (dir / "run").string();
  // A re-run with other methods leaves no file of the first run behind.
  ASSERT_EQ(runCli("compare -m uwb-ls,uwb-gn -o " + out).code, 0);
  EXPECT_TRUE(std::filesystem::exists(dir / "run" / "uwb-gn.tum"));
  ASSERT_EQ(runCli("compare -m uwb-kf -o " + out).code, 0);
  EXPECT_FALSE(std::filesystem::exists(dir / "run" / "uwb-gn.tum"));
  EXPECT_TRUE(std::filesystem::exists(dir / "run" / "uwb-kf.tum"));
  EXPECT_FALSE(std::filesystem::exists(dir / "run.lock"));
  for (const auto& e : std::filesystem::directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  // A live process holds the lock (this test's own): refused, naming it; the run is untouched.
  writeText(dir / "run.lock", std::to_string(getpid()) + "\n");
  expectFailureMentioning(runCli("compare -m uwb-gn -o " + out),
                          {"another run", std::to_string(getpid()), "run.lock"});
  EXPECT_TRUE(std::filesystem::exists(dir / "run" / "uwb-kf.tum"));
  // The lock of a process that is gone is taken over.
  const pid_t child = fork();
  if (child == 0) _exit(0);
  waitpid(child, nullptr, 0);
  writeText(dir / "run.lock", std::to_string(child) + "\n");
  EXPECT_EQ(runCli("compare -m uwb-gn -o " + out).code, 0);
  EXPECT_TRUE(std::filesystem::exists(dir / "run" / "uwb-gn.tum"));
}

TEST(Cli, ManifestNameCannotMoveTheOutput) {
  const auto dir = uwbloc::test::scratchDir();
  writeRanges(dir / "n.rawlog", 60);
  writeText(dir / "anchors.csv", "id,x,y,z\n1,0,0,2\n2,6,0,2\n3,0,6,2\n");
  const auto manifest = writeText(dir / "m.ini",
                                  "[dataset]\nname = ../../escaped\nrawlog = n.rawlog\n[anchors]\n"
                                  "anchors_csv = anchors.csv\n");
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  const auto r = runCli("compare -d " + manifest + " -m uwb-ls");
  std::filesystem::current_path(cwd);
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "runs" / "______escaped" / "metrics.json")) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir.parent_path().parent_path() / "escaped"));
}

TEST(Cli, UnknownMethodNamesInSetAndConfigAndAbsurdOptions) {
  const auto dir = uwbloc::test::scratchDir();
  expectFailureMentioning(runCli("compare --set uwb-kff.q=1 -o " + (dir / "r").string()),
                          {"uwb-kff", "is not a method"});
  const auto cfg = writeText(dir / "c.ini", "[uwb-ekf]\nq = 0.2\n[bogus]\nx = 1\n");
  expectFailureMentioning(runCli("compare --config " + cfg + " -o " + (dir / "r").string()),
                          {"c.ini", "[bogus]", "is not a method"});
  const auto pop = runCli("bench-optimizers --population 0");
  EXPECT_EQ(pop.code, 2) << pop.output;
  const auto rep = runCli("compare --repeat 100000000");
  EXPECT_EQ(rep.code, 2) << rep.output;
}

TEST(Cli, ARunOverTheMemoryLimitIsRefusedBeforeItStarts) {
  const auto dir = uwbloc::test::scratchDir();
  const auto out = (dir / "run").string();
  // 1e6 particles are about 92 MiB: refused under a 50 MiB limit, with the parts named.
  expectFailureMentioning(runCli("compare -m pf-sir:n=1000000 --max-memory 50M -o " + out),
                          {"error:", "pf-sir", "particles", "--max-memory", "50 MiB"});
  EXPECT_FALSE(std::filesystem::exists(out));
  const auto bad = runCli("compare -m uwb-ls --max-memory lots -o " + out);
  EXPECT_EQ(bad.code, 2);
  EXPECT_NE(bad.output.find("--max-memory"), std::string::npos) << bad.output;
  EXPECT_EQ(runCli("compare -m uwb-ls --max-memory 2G -o " + out).code, 0);
}

TEST(Cli, AReferenceThatDoesNotOverlapTheRunIsRefused) {
  const auto dir = uwbloc::test::scratchDir();
  writeRanges(dir / "o.rawlog", 60);
  writeText(dir / "anchors.csv", "id,x,y,z\n1,0,0,2\n2,6,0,2\n3,0,6,2\n");
  writeText(dir / "gt.txt", "100 1 1 0\n200 2 2 0\n");
  const auto manifest = writeText(dir / "m.ini",
                                  "[dataset]\nrawlog = o.rawlog\nground_truth = gt.txt\n"
                                  "ground_truth_format = time_xyphi\n[anchors]\n"
                                  "anchors_csv = anchors.csv\n");
  const auto out = (dir / "run").string();
  expectFailureMentioning(runCli("compare -d " + manifest + " -m uwb-ls -o " + out),
                          {"gt.txt", "covers 0 %", "--allow-partial-reference"});
  const auto allowed =
      runCli("compare -d " + manifest + " -m uwb-ls --allow-partial-reference -o " + out);
  // Allowed, but nothing overlaps the reference: the run is scored, warned and flagged, and a
  // result that cannot be scored is not a success.
  EXPECT_EQ(allowed.code, 3) << allowed.output;
  EXPECT_NE(allowed.output.find("WARNING"), std::string::npos) << allowed.output;
  EXPECT_NE(allowed.output.find("FLAGGED"), std::string::npos) << allowed.output;
}

TEST(Cli, NlosTrainEvalAndAFilterThatUsesTheModel) {
  const auto dir = uwbloc::test::scratchDir();
  // 300 ranges to anchors 1-3, every third one NLOS (received minus first-path power 10 dB
  // against 2 dB, 0.5 m long), with the truth columns an import with a reference writes.
  writeRanges(dir / "r.rawlog", 300);
  std::string csv = "t,anchor_id,range,rx_power_dbm,fp_power_dbm,true_range,error,nlos\n";
  char row[160];
  for (int k = 0; k < 300; ++k) {
    const bool nlos = k % 3 == 0;
    std::snprintf(row, sizeof row, "%.6f,%d,4.0,%.2f,-85.00,%.4f,%.4f,%d\n", 0.1 * k, 1 + k % 3,
                  nlos ? -75.0 + 0.01 * k : -83.0 - 0.01 * k, nlos ? 3.5 : 4.0, nlos ? 0.5 : 0.0,
                  nlos ? 1 : 0);
    csv += row;
  }
  const auto features = writeText(dir / "features.csv", csv);
  const auto model = (dir / "m.json").string();
  auto r = runCli("nlos train --data " + features + " --out " + model);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("power features"), std::string::npos) << r.output;  // auto: no CIR
  EXPECT_EQ(r.output.find("centred"), std::string::npos) << r.output;         // not by default
  r = runCli("nlos eval --model " + model + " --data " + features);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find(" 1.000 "), std::string::npos) << r.output;  // accuracy on its rows
  // A filter that uses it: every accepted range judged, and said so in metrics.json.
  // Anchors 2 m above the tag, each 4 m (3.464 m in the plane) from a tag at rest at the origin.
  const auto m = writeText(dir / "m.ini",
                           "[dataset]\nrawlog = r.rawlog\nrange_features = features.csv\n"
                           "ground_truth = gt.txt\nground_truth_format = time_xyphi\n"
                           "[anchors]\nanchors_csv = anchors.csv\n");
  writeText(dir / "gt.txt", "0 0 0 0\n10 0 0 0\n20 0 0 0\n30 0 0 0\n");
  writeText(dir / "anchors.csv", "id,x,y,z\n1,3.4641,0,2\n2,-1.7321,3,2\n3,-1.7321,-3,2\n");
  r = runCli("run -d " + m + " -m uwb-ekf:nlos_model=model:" + model + ",nlos_use=reject -o " +
             (dir / "run").string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream json(dir / "run" / "metrics.json");
  const std::string text((std::istreambuf_iterator<char>(json)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"nlos_model\": 100"), std::string::npos) << text.substr(0, 2000);
  // A model centred on its file's medians: the filter takes its place's from the first 32
  // ranges and lets the first 31 pass unjudged, 11 of the 100 NLOS ones. Of the other 89 the
  // trees reject most (their split sits at the edge of the training NLOS rows, and the early
  // medians drift with this log's powers), and no LOS range.
  const auto centred = (dir / "centred.json").string();
  r = runCli("nlos train --centre environment --data " + features + " --out " + centred);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("centred on each file's medians"), std::string::npos) << r.output;
  r = runCli("run -d " + m + " -m uwb-ekf:nlos_model=" + centred + ",nlos_use=reject -o " +
             (dir / "centred").string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream cjson(dir / "centred" / "metrics.json");
  const std::string ctext((std::istreambuf_iterator<char>(cjson)),
                          std::istreambuf_iterator<char>());
  const auto count = [&](const std::string& key) {  // the first count of that name
    for (auto at = ctext.find("\"" + key + "\": "); at != std::string::npos;
         at = ctext.find("\"" + key + "\": ", at + 1))
      if (std::isdigit(static_cast<unsigned char>(ctext[at + key.size() + 4])))
        return std::atoi(ctext.c_str() + at + key.size() + 4);
    return -1;
  };
  EXPECT_EQ(count("nlos_warming_up"), 31) << ctext.substr(0, 3000);
  EXPECT_GE(count("nlos_model"), 75) << ctext.substr(0, 3000);
  EXPECT_LE(count("nlos_model"), 89) << ctext.substr(0, 3000);
  EXPECT_EQ(count("nlos_model") + count("nlos_kept"), 300 - 31) << ctext.substr(0, 3000);
  // Ranges without powers cannot be judged: the table says so.
  const auto bare = writeText(dir / "bare.ini",
                              "[dataset]\nrawlog = r.rawlog\nground_truth = gt.txt\n"
                              "ground_truth_format = time_xyphi\n[anchors]\nanchors_csv = "
                              "anchors.csv\n");
  r = runCli("run -d " + bare + " -m uwb-ekf:nlos_model=" + model + " -o " +
             (dir / "bare").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("WARNING: uwb-ekf:nlos_model="), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("judged none of 300 ranges"), std::string::npos) << r.output;
  // A malformed row names its file and line; a missing model names the parameter.
  const auto bad = writeText(dir / "bad.csv", "t,anchor_id,range,nlos\n1,1,4,0\n2,1,x,1\n");
  expectFailureMentioning(runCli("nlos train --data " + bad + " --out " + model),
                          {"error:", bad + ":3", "'range'", "not a number"});
  expectFailureMentioning(
      runCli("run -d " + m + " -m uwb-ekf:nlos_model=" + (dir / "none.json").string()),
      {"error:", "nlos_model", "none.json"});
}
