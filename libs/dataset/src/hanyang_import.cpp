#include "uwbloc/dataset/hanyang_import.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

struct FeatureRow {
  double t;
  int id;
  double range, rssi, rssi_fp;
};

}  // namespace

TwrFile readHanyangStatic(const std::string& path) {
  TwrFile out;
  std::vector<int> col;  // indices of Distance, poll_tx, poll_rx, resp_tx, resp_rx
  const char* names[] = {"Distance", "poll_tx_ts", "poll_rx_ts", "resp_tx_ts", "resp_rx_ts"};
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    if (col.empty()) {
      for (const char* name : names) {
        const auto it = std::find(f.begin(), f.end(), name);
        if (it == f.end())
          throwInputError(path, line, std::string("missing column '") + name + "'");
        col.push_back(static_cast<int>(it - f.begin()));
      }
      return;
    }
    double v[5];
    for (int i = 0; i < 5; ++i) {
      const auto c = static_cast<size_t>(col[static_cast<size_t>(i)]);
      char* end = nullptr;
      v[i] = c < f.size() ? std::strtod(f[c].c_str(), &end) : NAN;
      if (c >= f.size() || f[c].empty() || end != f[c].c_str() + f[c].size() ||
          !std::isfinite(v[i])) {
        ++out.incomplete_rows;
        return;
      }
    }
    out.exchanges.push_back({static_cast<int64_t>(v[1]), static_cast<int64_t>(v[2]),
                             static_cast<int64_t>(v[3]), static_cast<int64_t>(v[4]), v[0]});
  });
  return out;
}

ImportSummary importHanyang(const std::string& run_dir, const std::string& out_dir,
                            const HanyangImportParams& params) {
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec)) throwInputError(run_dir, 0, "run folder not found");
  std::vector<std::string> anchor_files;
  for (const auto& entry : fs::directory_iterator(run_dir)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 5 && name[0] == 'A' && std::isdigit(static_cast<unsigned char>(name[1])) &&
        entry.path().extension() == ".csv")
      anchor_files.push_back(entry.path().string());
  }
  std::sort(anchor_files.begin(), anchor_files.end());
  if (anchor_files.empty())
    throwInputError(run_dir, 0, "no anchor files (A<id>.csv) in the run folder");
  const std::string trajectory = (fs::path(run_dir) / "trajectory.csv").string();

  std::vector<uwb::Anchor> anchors;
  std::vector<loc::Event> events;
  std::vector<FeatureRow> features;
  for (const auto& file : anchor_files) {
    uwb::Anchor anchor;
    bool have_anchor = false;
    forEachRow(file, [&](int line, const std::vector<std::string>& f) {
      if (!f.empty() && f[0] == "%time") return;
      if (f.size() != 9)
        throwInputError(file, line, "expected 9 fields, got " + std::to_string(f.size()));
      const double t = parseNumber(f[1], file, line, "field.stamp") * 1e-9;
      const int id = static_cast<int>(parseNumber(f[2], file, line, "field.id"));
      const Eigen::Vector3d pos(parseNumber(f[3], file, line, "field.x"),
                                parseNumber(f[4], file, line, "field.y"),
                                parseNumber(f[5], file, line, "field.z"));
      if (!have_anchor) {
        anchor = {id, pos};
        have_anchor = true;
      } else if (id != anchor.id || (pos - anchor.position).norm() > 0.05) {
        throwInputError(file, line, "anchor id or position differs from the file's first row");
      }
      uwb::Range r;
      r.t = t;
      r.anchor_id = id;
      r.range = parseNumber(f[6], file, line, "field.distanceFromTag");
      r.tag_on_robot << 0.0, 0.0, params.tag_height;
      r.rx_power_dbm = parseNumber(f[7], file, line, "field.rssi");
      r.fp_power_dbm = parseNumber(f[8], file, line, "field.rssi_fp");
      events.emplace_back(r);
      features.push_back({t, id, r.range, *r.rx_power_dbm, *r.fp_power_dbm});
    });
    if (!have_anchor) throwInputError(file, 0, "no ranges");
    if (uwb::findAnchor(anchors, anchor.id))
      throwInputError(file, 0, "anchor id " + std::to_string(anchor.id) + " appears twice");
    anchors.push_back(anchor);
  }
  loc::sortByTime(events);
  std::stable_sort(features.begin(), features.end(),
                   [](const FeatureRow& a, const FeatureRow& b) { return a.t < b.t; });

  std::vector<TimedPose> gt;
  forEachRow(trajectory, [&](int line, const std::vector<std::string>& f) {
    if (!f.empty() && f[0] == "timestamp") return;
    if (f.size() != 5)
      throwInputError(trajectory, line, "expected 5 fields, got " + std::to_string(f.size()));
    TimedPose p;
    p.t = parseNumber(f[0], trajectory, line, "timestamp") * 1e-9;
    p.pose << parseNumber(f[1], trajectory, line, "x"), parseNumber(f[2], trajectory, line, "y"),
        loc::wrapAngle(parseNumber(f[4], trajectory, line, "heading_degrees") * M_PI / 180.0);
    if (!gt.empty() && p.t < gt.back().t) throwInputError(trajectory, line, "time goes backwards");
    gt.push_back(p);
  });
  if (gt.empty()) throwInputError(trajectory, 0, "no reference rows");

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "uwb.rawlog").string(), events);
  writeFileAtomic((out / "ground_truth.tum").string(), formatTum(gt));

  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(anchors));
  char buf[256];

  std::string feat = "t,anchor_id,range,rx_power_dbm,fp_power_dbm\n";
  for (const auto& f : features) {
    std::snprintf(buf, sizeof buf, "%.6f,%d,%.6f,%.2f,%.2f\n", f.t, f.id, f.range, f.rssi,
                  f.rssi_fp);
    feat += buf;
  }
  writeFileAtomic((out / "range_features.csv").string(), feat);

  ManifestDraft m;
  m.comments = {"Imported by 'uwbloc import hanyang' from " + fs::absolute(run_dir).string()};
  m.name = "hanyang_" + fs::path(run_dir).lexically_normal().filename().string();
  m.rawlog = "uwb.rawlog";
  m.ground_truth = "ground_truth.tum";
  m.ground_truth_format = GroundTruthFormat::kTum;
  m.range_features = "range_features.csv";
  m.anchors_csv = "anchors.csv";
  m.tag_height = params.tag_height;
  ImportSummary summary;
  summary.manifest = writeManifest(out_dir, m);
  summary.ranges = static_cast<long>(events.size());
  summary.anchors = static_cast<long>(anchors.size());
  summary.ground_truth_rows = static_cast<long>(gt.size());
  return summary;
}

}  // namespace uwbloc::data
