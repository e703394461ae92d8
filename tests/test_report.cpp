// What a run shows: the plots (PNG content), report.html rendered in headless Chromium, and
// compare's parallel runs giving the figures of a serial one.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "test_helpers.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/html_report.hpp"
#include "uwbloc/evaluation/plots.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"

using namespace uwbloc;
namespace fs = std::filesystem;

namespace {

const data::Dataset& demo() {
  static const data::Dataset ds =
      data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  return ds;
}

// The demo through a position-only filter, PF-IBAS (map, swarm, NLOS decisions) and odometry.
const std::vector<eval::MethodSummary>& demoRuns() {
  static const auto runs = eval::evaluateMethods(
      demo(), {{"uwb-ekf", {}}, {"pf-ibas:n=200", {}}, {"odom", {}}}, 1, 1, 2);
  return runs;
}

// Share of pixels that differ from the background (white) and are coloured (not grey).
struct Ink {
  double any = 0.0, coloured = 0.0;
};
Ink inkOf(const cv::Mat& img) {
  long any = 0, coloured = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
      any += mn < 245;
      coloured += mx - mn > 60;
    }
  const double n = static_cast<double>(img.total());
  return {any / n, coloured / n};
}

std::string run(const std::string& cmd, int* code = nullptr) {
  std::string out;
  FILE* pipe = popen((cmd + " 2>/dev/null").c_str(), "r");
  std::array<char, 4096> buf{};
  while (pipe && fgets(buf.data(), buf.size(), pipe)) out += buf.data();
  const int status = pipe ? pclose(pipe) : -1;
  if (code) *code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return out;
}

// Headless Chromium (Debian's chromium-headless-shell, or chromium), or empty.
std::string browser() {
  for (const char* b : {"/usr/bin/chromium-headless-shell", "/usr/bin/chromium"})
    if (fs::exists(b)) return b;
  return {};
}

#define REQUIRE_BROWSER(b)                                                             \
  do {                                                                                 \
    if ((b).empty()) {                                                                 \
      if (::uwbloc::test::inCi())                                                      \
        FAIL() << "no headless Chromium (CI=true: the test command installs "          \
                  "chromium-headless-shell)";                                          \
      GTEST_SKIP() << "no headless Chromium: apt-get install chromium-headless-shell"; \
    }                                                                                  \
  } while (0)

// The page's status after its scripts ran (data-report-status of <body>).
std::string renderedStatus(const std::string& b, const fs::path& page) {
  const std::string dom = run(b +
                              " --headless --no-sandbox --disable-gpu --virtual-time-budget=15000"
                              " --dump-dom 'file://" +
                              fs::absolute(page).string() + "'");
  const std::string key = "data-report-status=\"";
  const auto at = dom.find(key);
  if (at == std::string::npos) return "(no status in the rendered page)";
  return dom.substr(at + key.size(), dom.find('"', at + key.size()) - at - key.size());
}

}  // namespace

TEST(Plots, EveryPictureIsWrittenAndShowsItsContent) {
  const auto dir = test::scratchDir() / "plots";
  const auto files = eval::writePlots(dir.string(), demo(), demoRuns());
  std::set<std::string> names;
  for (const auto& f : files) names.insert(f.file);
  for (const char* expected : {"trajectories.png", "error_cdf.png", "range_residuals.png",
                               "swarm_spread.png", "trajectory_uwb-ekf.png", "error_uwb-ekf.png",
                               "trajectory_pf-ibas_n-200.png", "error_odom.png"})
    EXPECT_TRUE(names.count(expected)) << expected;
  for (const auto& f : files) {
    const cv::Mat img = cv::imread((dir / f.file).string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty()) << f.file;
    EXPECT_GE(img.cols, 900) << f.file;
    const Ink ink = inkOf(img);
    // Axes, text, map and lines cover a few per cent of the picture; the palette's colours
    // (the methods' lines, the markers) some of it.
    EXPECT_GT(ink.any, 0.02) << f.file;
    EXPECT_GT(ink.coloured, 0.0005) << f.file;
  }
  // The trajectory picture carries the map: the demo's occupancy grid is mostly grey or dark.
  const Ink map = inkOf(cv::imread((dir / "trajectories.png").string()));
  EXPECT_GT(map.any, 0.2);
}

TEST(Plots, EveryRejectedRangeIsKeptWithItsReasonForTheResidualPlot) {
  for (const auto& m : demoRuns()) {
    std::map<std::string, long> kept;
    for (const auto& r : m.range_rejections) ++kept[r.reason];
    long total = 0;
    for (const auto& [reason, n] : kept) {
      EXPECT_EQ(n, m.rejected.at(reason)) << m.spec << " " << reason;
      total += n;
    }
    if (m.spec != "odom") {
      EXPECT_GT(total, 0) << m.spec;  // the demo has zero ranges
    }
  }
  std::string caption;
  const auto files = eval::writePlots((test::scratchDir() / "p").string(), demo(), demoRuns());
  for (const auto& f : files)
    if (f.file == "range_residuals.png") caption = f.caption;
  EXPECT_NE(caption.find("pf-ibas:n=200 did with each range"), std::string::npos) << caption;
}

TEST(Plots, WithoutMapOrReferenceTheTrajectoryIsStillDrawn) {
  data::Dataset ds;
  ds.name = "bare";
  eval::MethodSummary m;
  m.spec = "line";
  for (int k = 0; k < 50; ++k) m.trajectory.push_back({0.1 * k, {0.1 * k, 0.05 * k, 0.0}});
  const auto dir = test::scratchDir() / "plots_bare";
  const auto files = eval::writePlots(dir.string(), ds, {m});
  ASSERT_EQ(files.size(), 2u);  // all trajectories and the method's own; no reference to score
  EXPECT_GT(inkOf(cv::imread((dir / "trajectories.png").string())).coloured, 0.0005);
}

TEST(Report, RendersInHeadlessChromiumWithEveryChartDrawn) {
  const std::string b = browser();
  REQUIRE_BROWSER(b);
  const auto dir = test::scratchDir() / "report";
  eval::RunInfo info;
  info.plots = true;
  fs::create_directories(dir);
  eval::writeRunFiles(dir.string(), demo(), demoRuns(), info);
  const fs::path page = dir / "report.html";
  ASSERT_TRUE(fs::exists(page));
  // Self-contained: nothing is fetched from the network.
  std::ifstream in(page);
  const std::string html((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(html.find("src=\"http"), std::string::npos);
  EXPECT_NE(html.find("Chart.js v3"), std::string::npos) << "Chart.js is not inlined";
  EXPECT_EQ(renderedStatus(b, page), "ok");
  const fs::path shot = dir / "report.png";
  run(b +
      " --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1300,2200"
      " --virtual-time-budget=15000 --screenshot=" +
      shot.string() + " 'file://" + fs::absolute(page).string() + "'");
  const cv::Mat img = cv::imread(shot.string());
  ASSERT_FALSE(img.empty()) << "no screenshot";
  EXPECT_GT(inkOf(img).coloured, 0.002);
}

TEST(Report, TheBrowserCheckCatchesABrokenPage) {
  const std::string b = browser();
  REQUIRE_BROWSER(b);
  const auto dir = test::scratchDir() / "report_broken";
  fs::create_directories(dir);
  const std::string table = eval::formatTable(demo(), demoRuns());
  std::string html = eval::formatHtmlReport(demo(), demoRuns(), table, {}, dir.string());
  // A script error after the charts: the page must say so.
  std::string broken = html;
  broken.insert(broken.rfind("</body>"), "<script>undefinedFunction();</script>");
  std::ofstream(dir / "error.html") << broken;
  EXPECT_NE(renderedStatus(b, dir / "error.html").rfind("error:", 0), std::string::npos);
  // A chart with no data: every method's trajectory and the reference empty.
  data::Dataset empty = demo();
  empty.ground_truth.clear();
  empty.anchors.clear();
  std::vector<eval::MethodSummary> none = demoRuns();
  for (auto& m : none) m.trajectory.clear();
  none.resize(1);
  std::ofstream(dir / "empty.html") << eval::formatHtmlReport(empty, none, table, {}, dir.string());
  EXPECT_NE(renderedStatus(b, dir / "empty.html").find("trajectory is empty"), std::string::npos);
  // Without Chart.js the page still loads, without the interactive charts.
  std::ofstream(dir / "static.html")
      << eval::formatHtmlReport(demo(), demoRuns(), table, {}, dir.string(), "/no/chart.js");
  EXPECT_EQ(renderedStatus(b, dir / "static.html"), "static");
}

TEST(Parallel, TwoJobsGiveTheFiguresOfOneBitForBit) {
  const std::vector<eval::MethodJob> jobs{
      {"uwb-ekf", {}}, {"pf-ibas:n=150", {}}, {"uwb-pf:n=300", {}}, {"odom", {}}};
  auto strip = [](const std::string& text) {
    auto j = nlohmann::json::parse(text);
    // The timing, and which run solved a shared learning start (here the serial runs did, for
    // every later one in this process): the estimates are the same either way.
    for (auto& m : j["methods"]) {
      for (const char* k : {"ms_per_step", "realtime_factor"}) m.erase(k);
      m["events"].erase("range_model_reused");
    }
    return j.dump(1);
  };
  const auto serial = eval::evaluateMethods(demo(), jobs, 2, 5, 1);
  const auto parallel = eval::evaluateMethods(demo(), jobs, 2, 5, 2);
  const std::string a = strip(eval::formatMetricsJson(demo(), serial));
  const std::string b = strip(eval::formatMetricsJson(demo(), parallel));
  EXPECT_EQ(a, b);
  // And the same as evaluateMethod, one method after another.
  std::vector<eval::MethodSummary> one_by_one;
  for (const auto& j : jobs) one_by_one.push_back(eval::evaluateMethod(demo(), j.spec, 2, 5));
  EXPECT_EQ(strip(eval::formatMetricsJson(demo(), one_by_one)), a);
  ASSERT_EQ(parallel.size(), 4u);
  EXPECT_EQ(parallel[1].seed_runs.size(), 2u);
  EXPECT_FALSE(parallel[1].trajectory.empty());
}
