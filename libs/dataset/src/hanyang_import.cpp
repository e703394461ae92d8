#include "uwbloc/dataset/hanyang_import.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/tag_fit.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

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
          !(std::abs(v[i]) < 9e18)) {  // finite, and within int64 for the timestamps
        ++out.incomplete_rows;
        return;
      }
    }
    out.exchanges.push_back({static_cast<int64_t>(v[1]), static_cast<int64_t>(v[2]),
                             static_cast<int64_t>(v[3]), static_cast<int64_t>(v[4]), v[0]});
  });
  return out;
}

namespace {

// The run's anchor files, A<id>.csv, sorted.
std::vector<std::string> anchorFiles(const std::string& run_dir) {
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec)) throwInputError(run_dir, 0, "run folder not found");
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(run_dir)) {
    const std::string name = entry.path().filename().string();
    if (name.size() > 5 && name[0] == 'A' && std::isdigit(static_cast<unsigned char>(name[1])) &&
        entry.path().extension() == ".csv")
      files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throwInputError(run_dir, 0, "no anchor files (A<id>.csv) in the run folder");
  return files;
}

// One anchor's file: its ranges (with received and first-path power) into `events`; returns the
// anchor, whose id and position every row repeats.
uwb::Anchor readAnchorFile(const std::string& file, const HanyangImportParams& params,
                           std::vector<loc::Event>& events, std::map<std::string, long>& skipped) {
  uwb::Anchor anchor;
  bool have_anchor = false;
  forEachRow(file, [&](int line, const std::vector<std::string>& f) {
    if (!f.empty() && f[0] == "%time") return;
    if (f.size() != 9)
      throwInputError(file, line, "expected 9 fields, got " + std::to_string(f.size()));
    const int id = parseId(f[2], file, line, "field.id");
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
    r.t = parseNumber(f[1], file, line, "field.stamp") * 1e-9;
    if (const char* problem = timestampProblem(r.t))
      return void(++skipped[std::string("range_") + problem]);
    r.anchor_id = id;
    r.range = parseNumber(f[6], file, line, "field.distanceFromTag");
    r.tag_on_robot << 0.0, 0.0, params.tag_height;
    r.rx_power_dbm = parseNumber(f[7], file, line, "field.rssi");
    r.fp_power_dbm = parseNumber(f[8], file, line, "field.rssi_fp");
    events.emplace_back(r);
  });
  if (!have_anchor) throwInputError(file, 0, "no ranges");
  return anchor;
}

// trajectory.csv: timestamp [ns], x, y, z, heading [deg].
std::vector<TimedPose> readReference(const std::string& trajectory,
                                     std::map<std::string, long>& skipped) {
  std::vector<TimedPose> gt;
  forEachRow(trajectory, [&](int line, const std::vector<std::string>& f) {
    if (!f.empty() && f[0] == "timestamp") return;
    if (f.size() != 5)
      throwInputError(trajectory, line, "expected 5 fields, got " + std::to_string(f.size()));
    TimedPose p;
    p.t = parseNumber(f[0], trajectory, line, "timestamp") * 1e-9;
    p.pose << parseNumber(f[1], trajectory, line, "x"), parseNumber(f[2], trajectory, line, "y"),
        loc::wrapAngle(parseNumber(f[4], trajectory, line, "heading_degrees") * M_PI / 180.0);
    if (const char* problem = timestampProblem(p.t))
      return void(++skipped[std::string("reference_") + problem]);
    if (!p.pose.allFinite()) return void(++skipped["reference_non_finite_pose"]);
    if (!gt.empty() && p.t < gt.back().t) throwInputError(trajectory, line, "time goes backwards");
    gt.push_back(p);
  });
  if (gt.empty()) throwInputError(trajectory, 0, "no reference rows");
  return gt;
}

// Each range's true distance and label against the reference. The reference is the robot's
// pose, not the tag's: the tag's place on the robot (lever arm) is estimated from the data
// (fitTagOnRobot, tag_fit.hpp: within 1 m on a 5 cm grid, the least median deviation from each
// anchor's median error) at the given height. The true distance runs from that tag
// position, at the tag height, to the anchor. A range is NLOS when its error departs from its
// anchor's median error (a constant bias is no NLOS) by more than max(0.3 m, 3 robust std);
// 0.3 m is three times the DW1000's LOS ranging std (about 0.1 m).
std::vector<RangeLabel> rangeLabels(const std::vector<loc::Event>& events,
                                    const std::vector<uwb::Anchor>& anchors,
                                    const std::vector<TimedPose>& gt, double tag_height,
                                    ImportSummary& summary) {
  std::vector<RangeLabel> labels(events.size());
  const auto samples = rangesBesideReference(events, anchors, gt);
  if (samples.size() < 50) return labels;
  const Eigen::Vector3d origin(0.0, 0.0, tag_height);
  const double at_origin = loc::medianOf(rangeDeviations(samples, origin));
  const TagFit fit = fitTagOnRobot(samples, origin, true, false);
  const auto dev = rangeDeviations(samples, fit.tag);
  const double threshold = std::max(0.3, 3.0 * 1.4826 * loc::medianOf(dev));
  long nlos = 0;
  for (size_t k = 0; k < samples.size(); ++k) {
    const auto& s = samples[k];
    auto& label = labels[s.event];
    label.true_range = (uwb::tagPosition(s.pose, fit.tag) - s.anchor).norm();
    label.nlos = dev[k] > threshold;
    nlos += label.nlos;
  }
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "range_features.csv: %zu ranges labelled against the reference: tag at (%.2f, "
                "%.2f) m on the robot (median deviation %.3f m, %.3f m at the origin); %ld "
                "NLOS (more than %.3f m from their anchor's median error)",
                samples.size(), fit.tag.x(), fit.tag.y(), fit.deviation, at_origin, nlos,
                threshold);
  summary.notes.push_back(buf);
  for (const auto& [link, b] : fit.bias) {
    std::snprintf(buf, sizeof buf, "  anchor %d: median range error %+.3f m", link.first, b);
    summary.notes.push_back(buf);
  }
  return labels;
}

}  // namespace

ImportSummary importHanyang(const std::string& run_dir, const std::string& out_dir,
                            const HanyangImportParams& params) {
  ImportSummary summary;
  std::vector<uwb::Anchor> anchors;
  std::vector<loc::Event> events;
  for (const auto& file : anchorFiles(run_dir)) {
    const uwb::Anchor anchor = readAnchorFile(file, params, events, summary.skipped);
    if (uwb::findAnchor(anchors, anchor.id))
      throwInputError(file, 0, "anchor id " + std::to_string(anchor.id) + " appears twice");
    anchors.push_back(anchor);
  }
  loc::sortByTime(events);
  const auto gt = readReference((fs::path(run_dir) / "trajectory.csv").string(), summary.skipped);

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "uwb.rawlog").string(), events);
  writeFileAtomic((out / "ground_truth.tum").string(), formatTum(gt));
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(anchors));
  const auto truth = rangeLabels(events, anchors, gt, params.tag_height, summary);
  writeFileAtomic((out / "range_features.csv").string(), formatRangeFeatures(events, &truth));

  ManifestDraft m;
  m.comments = {"Imported by 'uwbloc import hanyang' from " + fs::absolute(run_dir).string()};
  m.name = "hanyang_" + fs::path(run_dir).lexically_normal().filename().string();
  m.rawlog = "uwb.rawlog";
  m.ground_truth = "ground_truth.tum";
  m.ground_truth_format = GroundTruthFormat::kTum;
  m.range_features = "range_features.csv";
  m.anchors_csv = "anchors.csv";
  m.tag_height = params.tag_height;
  summary.manifest = writeManifest(out_dir, m);
  summary.ranges = static_cast<long>(events.size());
  summary.anchors = static_cast<long>(anchors.size());
  summary.ground_truth_rows = static_cast<long>(gt.size());
  return summary;
}

}  // namespace uwbloc::data
