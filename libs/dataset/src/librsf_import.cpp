#include "uwbloc/dataset/librsf_import.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "odometry_poses.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

struct OdomRow {
  double t, v, w, vy;
};

struct Parsed {
  std::vector<uwb::Range> ranges;
  std::vector<double> variances;
  std::vector<uwb::Anchor> anchors;
  std::vector<OdomRow> odometry;
  std::vector<TimedPose> reference;
};

void readFile(const std::string& path, Parsed& p, ImportSummary& s, bool reference_only) {
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    const std::string& type = f[0];
    auto number = [&](size_t i, const char* name) {
      return parseNumber(f[i], path, line, std::string(type) + " " + name);
    };
    auto time = [&]() -> std::optional<double> {
      const double t = number(1, "time");
      if (const char* problem = timestampProblem(t)) {
        ++s.skipped[type + "_" + problem];
        return std::nullopt;
      }
      return t;
    };
    if (type == "point2" || type == "gt2") {
      if (f.size() < 4) throwInputError(path, line, type + ": expected 't x y'");
      const auto t = time();
      if (!t) return;
      TimedPose g;
      g.t = *t;
      g.pose << number(2, "x"), number(3, "y"), 0.0;
      if (!g.pose.allFinite()) throwInputError(path, line, type + ": non-finite position");
      if (!p.reference.empty() && g.t < p.reference.back().t)
        throwInputError(path, line, type + ": time goes backwards");
      p.reference.push_back(g);
      return;
    }
    if (reference_only) return void(++s.skipped["reference_file_" + type]);
    if (type == "range2") {
      if (f.size() != 7 && f.size() != 8)
        throwInputError(
            path, line,
            "range2: expected 't range variance anchor_x anchor_y anchor_id [snr]', got " +
                std::to_string(f.size() - 1) + " fields");
      const auto t = time();
      if (!t) return;
      uwb::Range r;
      r.t = *t;
      r.range = number(2, "range");
      const double variance = number(3, "variance");
      const Eigen::Vector3d anchor(number(4, "anchor_x"), number(5, "anchor_y"), 0.0);
      r.anchor_id = parseId(f[6], path, line, "range2 anchor_id");
      if (!std::isfinite(r.range) || !anchor.allFinite())
        return void(++s.skipped["range2_non_finite"]);
      if (const uwb::Anchor* a = uwb::findAnchor(p.anchors, r.anchor_id)) {
        if ((a->position - anchor).norm() > 1e-3)
          throwInputError(path, line,
                          "range2: anchor " + f[6] + " is elsewhere than on its first line");
      } else {
        p.anchors.push_back({r.anchor_id, anchor});
      }
      if (variance > 0 && std::isfinite(variance)) p.variances.push_back(variance);
      p.ranges.push_back(r);
      return;
    }
    if (type == "odom2diff") {
      if (f.size() < 9)
        throwInputError(path, line,
                        "odom2diff: expected 't v_right v_left v_y wheel_base ... var_right "
                        "var_left var_y', got " +
                            std::to_string(f.size() - 1) + " fields");
      const auto t = time();
      if (!t) return;
      const double vr = number(2, "v_right"), vl = number(3, "v_left"), vy = number(4, "v_y"),
                   base = number(5, "wheel_base");
      if (!(base > 0.0)) throwInputError(path, line, "odom2diff: wheel_base must be > 0");
      if (!std::isfinite(vr) || !std::isfinite(vl) || !std::isfinite(vy))
        return void(++s.skipped["odom2diff_non_finite"]);
      if (!p.odometry.empty() && *t <= p.odometry.back().t)
        return void(++s.skipped["odom2diff_time_not_increasing"]);
      p.odometry.push_back({*t, 0.5 * (vr + vl), (vr - vl) / base, vy});
      return;
    }
    ++s.skipped["other_type_" + type];
  });
}

}  // namespace

ImportSummary importLibrsf(const std::string& file, const std::string& out_dir,
                           const std::string& reference) {
  ImportSummary s;
  Parsed p;
  readFile(file, p, s, false);
  std::string ref_file = reference;
  if (ref_file.empty()) {
    const std::string name = fs::path(file).filename().string();
    const auto at = name.find("_Input");
    if (at != std::string::npos) {
      const fs::path candidate =
          fs::path(file).parent_path() / (name.substr(0, at) + "_GT" + name.substr(at + 6));
      std::error_code ec;
      if (fs::is_regular_file(candidate, ec)) ref_file = candidate.string();
    }
  }
  if (!ref_file.empty()) {
    if (!p.reference.empty())
      throwInputError(ref_file, 0, "the input file already holds reference lines");
    readFile(ref_file, p, s, true);
  }
  if (p.ranges.empty()) throwInputError(file, 0, "no range2 line");

  std::vector<loc::Event> events;
  for (const auto& r : p.ranges) events.emplace_back(r);
  for (size_t k = 1; k < p.odometry.size(); ++k) {
    const OdomRow& o = p.odometry[k];
    const double dt = o.t - p.odometry[k - 1].t;
    loc::OdometryIncrement inc;
    inc.t = o.t;
    // The arc of speed v and yaw rate w, plus the sideways slip v_y at the mid heading, over dt.
    inc.delta = arcIncrement(o.v, o.w, dt);
    const double mid = inc.delta.z() / 2;
    inc.delta.x() -= std::sin(mid) * o.vy * dt;
    inc.delta.y() += std::cos(mid) * o.vy * dt;
    events.emplace_back(inc);
  }
  loc::sortByTime(events);

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "librsf.rawlog").string(), events);
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(p.anchors));
  ManifestDraft m;
  m.comments = {"Imported by 'uwbloc import librsf' from " + fs::absolute(file).string()};
  m.name = "librsf_" + fs::path(file).stem().string();
  m.rawlog = "librsf.rawlog";
  m.anchors_csv = "anchors.csv";
  m.tag_height = 0.0;
  if (!p.reference.empty()) {
    writeFileAtomic((out / "ground_truth.tum").string(), formatTum(p.reference));
    m.ground_truth = "ground_truth.tum";
    m.ground_truth_format = GroundTruthFormat::kTum;
    m.reference_heading = false;
    s.notes.push_back("Reference: " + std::to_string(p.reference.size()) + " positions" +
                      (ref_file.empty() ? "" : " from " + ref_file) + " (no heading)");
  } else {
    s.notes.emplace_back("WARNING: no reference (point2 lines, or a _GT file beside the input)");
  }
  if (!p.variances.empty()) {
    std::vector<double> v = p.variances;
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    m.uwb_sigma = std::sqrt(v[v.size() / 2]);
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "Range noise: the lines' median variance %.4g m^2, sigma %.4g m (the manifest's "
                  "[uwb] sigma)",
                  v[v.size() / 2], *m.uwb_sigma);
    s.notes.emplace_back(buf);
  }
  s.manifest = writeManifest(out_dir, m);
  s.ranges = static_cast<long>(p.ranges.size());
  s.anchors = static_cast<long>(p.anchors.size());
  s.ground_truth_rows = static_cast<long>(p.reference.size());
  return s;
}

}  // namespace uwbloc::data
