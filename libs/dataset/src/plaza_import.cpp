#include "uwbloc/dataset/plaza_import.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

struct DrRow {
  double t, distance, heading_change;
};

// The increment of one dead-reckoning row: the distance along the mean heading of the step,
// forward (sign +1) or backward (-1) in the reference's heading convention.
Eigen::Vector3d increment(const DrRow& r, double sign) {
  return {sign * r.distance * std::cos(r.heading_change / 2),
          sign * r.distance * std::sin(r.heading_change / 2), r.heading_change};
}

// Which way the odometry's distance points in the reference's heading convention, from the data:
// dead reckoning from the first reference pose in either convention, compared with the
// reference over the first 30 m travelled (or the whole run if shorter). Plaza recordings come
// with either convention (Plaza2's odometry runs backwards against its reference's heading).
double detectDirection(const std::vector<DrRow>& dr, const std::vector<TimedPose>& gt,
                       double* error_forward, double* error_backward) {
  double err[2] = {0.0, 0.0};
  for (int k = 0; k < 2; ++k) {
    const double sign = k == 0 ? 1.0 : -1.0;
    Eigen::Vector3d pose = gt.front().pose;
    double travelled = 0.0, sum = 0.0;
    long n = 0;
    for (const auto& r : dr) {
      if (r.t <= gt.front().t) continue;
      pose = loc::composePose(pose, increment(r, sign));
      travelled += std::abs(r.distance);
      const auto it = std::lower_bound(gt.begin(), gt.end(), r.t,
                                       [](const TimedPose& p, double t) { return p.t < t; });
      if (it == gt.end()) break;
      sum += (it->pose.head<2>() - pose.head<2>()).squaredNorm();
      ++n;
      if (travelled > 30.0) break;
    }
    err[k] = n > 0 ? std::sqrt(sum / n) : 0.0;
  }
  *error_forward = err[0];
  *error_backward = err[1];
  return err[1] < err[0] ? -1.0 : 1.0;
}

// The file prefix of a Plaza folder ("Plaza2" for Plaza2_DR.txt).
std::string plazaPrefix(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throwInputError(dir, 0, "folder not found");
  std::string prefix;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.size() > 7 && n.rfind("_DR.txt") == n.size() - 7) prefix = n.substr(0, n.size() - 7);
  }
  if (prefix.empty()) throwInputError(dir, 0, "no Plaza*_DR.txt file");
  return prefix;
}

// The dead-reckoning rows (t, distance, heading change), bad rows skipped and counted.
std::vector<DrRow> readDeadReckoning(const std::string& dr, ImportSummary& summary) {
  std::vector<DrRow> dr_rows;
  forEachRow(dr, [&](int line, const std::vector<std::string>& f) {
    if (f.size() < 3) throwInputError(dr, line, "expected 't distance heading_change'");
    const DrRow r{parseNumber(f[0], dr, line, "t"), parseNumber(f[1], dr, line, "distance"),
                  parseNumber(f[2], dr, line, "heading_change")};
    if (const char* problem = timestampProblem(r.t))
      return void(++summary.skipped[std::string("odometry_") + problem]);
    if (!std::isfinite(r.distance) || !std::isfinite(r.heading_change))
      return void(++summary.skipped["odometry_non_finite"]);
    if (!dr_rows.empty() && r.t < dr_rows.back().t)
      return void(++summary.skipped["odometry_out_of_order"]);
    dr_rows.push_back(r);
  });
  return dr_rows;
}

}  // namespace

ImportSummary importPlaza(const std::string& dir, const std::string& out_dir) {
  const std::string prefix = plazaPrefix(dir);
  const auto file = [&](const char* suffix) {
    return (fs::path(dir) / (prefix + suffix)).string();
  };

  ImportSummary summary;
  std::vector<loc::Event> events;
  const std::vector<DrRow> dr_rows = readDeadReckoning(file("_DR.txt"), summary);
  std::vector<uwb::Anchor> anchors;
  const std::string tl = file("_TL.txt");
  forEachRow(tl, [&](int line, const std::vector<std::string>& f) {
    if (f.size() < 3) throwInputError(tl, line, "expected 'id x y'");
    anchors.push_back({parseId(f[0], tl, line, "id"),
                       {parseNumber(f[1], tl, line, "x"), parseNumber(f[2], tl, line, "y"), 0.0}});
  });
  const std::string td = file("_TD.txt");
  long ranges = 0;
  forEachRow(td, [&](int line, const std::vector<std::string>& f) {
    if (f.size() < 4) throwInputError(td, line, "expected 't sender beacon range'");
    uwb::Range r;
    r.t = parseNumber(f[0], td, line, "t");
    if (const char* problem = timestampProblem(r.t))
      return void(++summary.skipped[std::string("range_") + problem]);
    r.anchor_id = parseId(f[2], td, line, "beacon");
    r.range = parseNumber(f[3], td, line, "range");
    r.tag_on_robot.setZero();
    events.emplace_back(r);
    ++ranges;
  });
  const auto gt = readGroundTruth(file("_GT.txt"), GroundTruthFormat::kTimeXyPhi);
  double err_forward = 0.0, err_backward = 0.0;
  const double sign = detectDirection(dr_rows, gt, &err_forward, &err_backward);
  for (const auto& r : dr_rows) {
    loc::OdometryIncrement o;
    o.t = r.t;
    o.delta = increment(r, sign);
    events.emplace_back(o);
  }
  loc::sortByTime(events);

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "plaza.rawlog").string(), events);
  writeFileAtomic((out / "ground_truth.tum").string(), formatTum(gt));
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(anchors));
  ManifestDraft m;
  char direction[200];
  std::snprintf(direction, sizeof direction,
                "Odometry distance taken %s in the reference's heading convention (dead reckoning "
                "over the first 30 m: %.2f m RMS forward, %.2f m backward)",
                sign > 0 ? "forward" : "backward", err_forward, err_backward);
  m.comments = {"Imported by 'uwbloc import plaza' from " + fs::absolute(dir).string(), direction};
  m.name = "plaza_" + prefix;
  m.rawlog = "plaza.rawlog";
  m.ground_truth = "ground_truth.tum";
  m.ground_truth_format = GroundTruthFormat::kTum;
  m.anchors_csv = "anchors.csv";
  m.tag_height = 0.0;
  summary.manifest = writeManifest(out_dir, m);
  summary.notes.push_back(direction);
  summary.ranges = ranges;
  summary.anchors = static_cast<long>(anchors.size());
  summary.ground_truth_rows = static_cast<long>(gt.size());
  return summary;
}

}  // namespace uwbloc::data
