#include "uwbloc/dataset/plaza_import.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "mat_file.hpp"
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

// The file prefix of a Plaza folder ("Plaza2" for Plaza2_DR.txt, or for Plaza2.mat).
std::string plazaPrefix(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throwInputError(dir, 0, "folder not found");
  std::string from_txt, from_mat;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.size() > 7 && n.rfind("_DR.txt") == n.size() - 7) from_txt = n.substr(0, n.size() - 7);
    if (n.size() > 4 && n.rfind(".mat") == n.size() - 4) from_mat = n.substr(0, n.size() - 4);
  }
  if (!from_txt.empty()) return from_txt;
  if (!from_mat.empty()) return from_mat;
  throwInputError(dir, 0, "no Plaza*_DR.txt and no Plaza*.mat file");
  return {};
}

// A table of the recording: its <prefix>_<name>.txt rows, else the matrix `name` of
// <prefix>.mat (GTSAM's layout keeps the reference and the beacons there). Rows of at least
// `columns` numbers; errors name the file and line (for the .mat, the variable and row).
struct Table {
  std::string source;  ///< for messages: the file, or "<file> variable <name>"
  std::vector<int> lines;
  std::vector<std::vector<double>> rows;
};

Table readTable(const std::string& dir, const std::string& prefix, const std::string& name,
                size_t columns) {
  const fs::path txt = fs::path(dir) / (prefix + "_" + name + ".txt");
  const fs::path mat = fs::path(dir) / (prefix + ".mat");
  std::error_code ec;
  Table t;
  if (fs::is_regular_file(txt, ec)) {
    t.source = txt.string();
    forEachRow(t.source, [&](int line, const std::vector<std::string>& f) {
      if (f.size() < columns)
        throwInputError(
            t.source, line,
            "expected " + std::to_string(columns) + " numbers, got " + std::to_string(f.size()));
      std::vector<double> row;
      for (size_t i = 0; i < f.size(); ++i)
        row.push_back(parseNumber(f[i], t.source, line, "column " + std::to_string(i + 1)));
      t.rows.push_back(std::move(row));
      t.lines.push_back(line);
    });
    return t;
  }
  if (!fs::is_regular_file(mat, ec))
    throwInputError(dir, 0,
                    "neither " + txt.filename().string() + " nor " + mat.filename().string() +
                        " (for the " + name + " table)");
  t.source = mat.string() + " variable " + name;
  t.rows = readMatMatrix(mat.string(), name);
  for (size_t r = 0; r < t.rows.size(); ++r) {
    t.lines.push_back(static_cast<int>(r + 1));
    if (t.rows[r].size() < columns)
      throwInputError(t.source, 0,
                      "has " + std::to_string(t.rows[r].size()) + " columns, expected at least " +
                          std::to_string(columns));
  }
  return t;
}

// The dead-reckoning rows (t, distance, heading change), bad rows skipped and counted.
std::vector<DrRow> readDeadReckoning(const Table& dr, ImportSummary& summary) {
  std::vector<DrRow> dr_rows;
  for (const auto& f : dr.rows) {
    const DrRow r{f[0], f[1], f[2]};
    if (const char* problem = timestampProblem(r.t)) {
      ++summary.skipped[std::string("odometry_") + problem];
      continue;
    }
    if (!std::isfinite(r.distance) || !std::isfinite(r.heading_change)) {
      ++summary.skipped["odometry_non_finite"];
      continue;
    }
    if (!dr_rows.empty() && r.t < dr_rows.back().t) {
      ++summary.skipped["odometry_out_of_order"];
      continue;
    }
    dr_rows.push_back(r);
  }
  return dr_rows;
}

int tableId(const Table& t, size_t k, size_t column, const char* field) {
  const double v = t.rows[k][column];
  if (!(std::abs(v) < 1e9) || v != std::floor(v)) {
    char value[40];
    std::snprintf(value, sizeof value, "%.17g", v);
    throwInputError(
        t.source, t.lines[k],
        std::string("field '") + field + "': expected an integer id (|id| < 1e9), got " + value);
  }
  return static_cast<int>(v);
}

}  // namespace

ImportSummary importPlaza(const std::string& dir, const std::string& out_dir) {
  const std::string prefix = plazaPrefix(dir);
  ImportSummary summary;
  std::vector<loc::Event> events;
  const Table dr = readTable(dir, prefix, "DR", 3), tl = readTable(dir, prefix, "TL", 3),
              td = readTable(dir, prefix, "TD", 4), gt_table = readTable(dir, prefix, "GT", 4);
  const std::vector<DrRow> dr_rows = readDeadReckoning(dr, summary);
  std::vector<uwb::Anchor> anchors;
  for (size_t k = 0; k < tl.rows.size(); ++k) {
    const Eigen::Vector3d p(tl.rows[k][1], tl.rows[k][2], 0.0);
    if (!p.allFinite()) throwInputError(tl.source, tl.lines[k], "non-finite beacon position");
    anchors.push_back({tableId(tl, k, 0, "id"), p});
  }
  long ranges = 0;
  for (size_t k = 0; k < td.rows.size(); ++k) {
    uwb::Range r;
    r.t = td.rows[k][0];
    if (const char* problem = timestampProblem(r.t)) {
      ++summary.skipped[std::string("range_") + problem];
      continue;
    }
    r.anchor_id = tableId(td, k, 2, "beacon");
    r.range = td.rows[k][3];
    r.tag_on_robot.setZero();
    events.emplace_back(r);
    ++ranges;
  }
  std::vector<TimedPose> gt;
  for (size_t k = 0; k < gt_table.rows.size(); ++k) {
    const auto& f = gt_table.rows[k];
    TimedPose p{f[0], Eigen::Vector3d(f[1], f[2], f[3])};
    if (!p.pose.allFinite() || timestampProblem(p.t))
      throwInputError(gt_table.source, gt_table.lines[k], "non-finite value or unusable time");
    if (!gt.empty() && p.t < gt.back().t)
      throwInputError(gt_table.source, gt_table.lines[k], "time goes backwards");
    gt.push_back(p);
  }
  if (gt.empty()) throwInputError(gt_table.source, 0, "no reference rows");
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
  summary.notes.push_back("Tables read from: DR " + dr.source + "; TD " + td.source + "; TL " +
                          tl.source + "; GT " + gt_table.source);
  summary.ranges = ranges;
  summary.anchors = static_cast<long>(anchors.size());
  summary.ground_truth_rows = static_cast<long>(gt.size());
  return summary;
}

}  // namespace uwbloc::data
