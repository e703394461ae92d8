#include "uwbloc/dataset/manifest.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <set>
#include <sstream>
#include <utility>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ini_file.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {
constexpr std::pair<GroundTruthFormat, const char*> kFormatNames[] = {
    {GroundTruthFormat::kStepXyPhi, "step_xyphi"},
    {GroundTruthFormat::kTimeXyPhi, "time_xyphi"},
    {GroundTruthFormat::kTum, "tum"},
    {GroundTruthFormat::kNone, "none"},
};
}  // namespace

GroundTruthFormat parseGroundTruthFormat(const std::string& text) {
  if (text.empty()) return GroundTruthFormat::kNone;
  for (const auto& [format, name] : kFormatNames)
    if (text == name) return format;
  throw InputError("unknown ground-truth format '" + text +
                   "' (expected step_xyphi, time_xyphi or tum)");
}

const char* toString(GroundTruthFormat f) {
  for (const auto& [format, name] : kFormatNames)
    if (format == f) return name;
  return "none";
}

namespace {
std::string number(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}
}  // namespace

std::string formatManifest(const ManifestDraft& d) {
  std::ostringstream ini;
  for (const auto& c : d.comments) ini << "# " << c << "\n";
  ini << "[dataset]\nname = " << d.name << "\nrawlog = " << d.rawlog << "\n";
  if (!d.ground_truth.empty())
    ini << "ground_truth = " << d.ground_truth
        << "\nground_truth_format = " << toString(d.ground_truth_format) << "\n";
  if (d.gt_max_gap) ini << "gt_max_gap = " << number("%.3g", *d.gt_max_gap) << "\n";
  if (!d.ground_truth.empty() && !d.reference_heading) ini << "reference_heading = false\n";
  if (!d.map.empty()) ini << "map = " << d.map << "\n";
  if (!d.range_features.empty()) ini << "range_features = " << d.range_features << "\n";
  ini << "\n[anchors]\n";
  if (!d.anchors_csv.empty()) ini << "anchors_csv = " << d.anchors_csv << "\n";
  if (!d.bias_csv.empty()) ini << "bias_csv = " << d.bias_csv << "\n";
  for (size_t i = 0; d.anchors_csv.empty() && i < d.anchors.size(); ++i) {
    const auto& a = d.anchors[i];
    const std::string key = "beacon_" + number("%03.0f", static_cast<double>(i + 1)) + "_";
    ini << key << "ID = " << a.id << "\n"
        << key << "X = " << number("%.6g", a.position.x()) << "\n"
        << key << "Y = " << number("%.6g", a.position.y()) << "\n"
        << key << "Z = " << number("%.6g", a.position.z()) << "\n";
  }
  if (d.tag_height || d.lever_arm || !d.tags.empty()) ini << "\n[tag]\n";
  for (const auto& [id, p] : d.tags)
    ini << "tag_" << id << " = " << number("%.4f", p.x()) << " " << number("%.4f", p.y()) << " "
        << number("%.4f", p.z()) << "\n";
  if (d.tag_height) ini << "height = " << number("%.4f", *d.tag_height) << "\n";
  if (d.lever_arm)
    ini << "lever_arm_x = " << number("%.4f", d.lever_arm->x())
        << "\nlever_arm_y = " << number("%.4f", d.lever_arm->y()) << "\n";
  if (d.uwb_sigma)
    ini << "\n[uwb]\n# The range noise the source states: every UWB method's default sigma.\nsigma "
           "= "
        << number("%.6g", *d.uwb_sigma) << "\n";
  if (d.bounds_range_sigma || d.bounds_odometry) ini << "\n[bounds]\n";
  if (d.bounds_range_sigma)
    ini << "# The LOS range noise, for the Cramer-Rao bounds.\nrange_sigma = "
        << number("%.6g", *d.bounds_range_sigma) << "\n";
  if (d.bounds_odometry)
    ini << "# For 'motion = odometry': the odometry noise.\nodom_sigma_xy_per_m = "
        << number("%.6g", d.bounds_odometry->x())
        << "\nodom_sigma_theta_per_rad = " << number("%.6g", d.bounds_odometry->y())
        << "\nodom_sigma_theta_per_m = " << number("%.6g", d.bounds_odometry->z()) << "\n";
  return ini.str();
}

std::string writeManifest(const std::string& dir, const ManifestDraft& draft) {
  const std::string path = (fs::path(dir) / "dataset.ini").string();
  writeFileAtomic(path, formatManifest(draft));
  return path;
}

std::vector<uwb::Anchor> loadAnchorsCsv(const std::string& path, IdNumbering* names,
                                        std::optional<double> z_when_absent, bool* without_z) {
  std::vector<std::pair<int, std::vector<std::string>>> rows;
  bool header = false;
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    // A header: the first row, with no number among its coordinates ("id,x,y,z", "name;X;Y;Z").
    if (rows.empty() && !header && f.size() >= 2 &&
        std::none_of(f.begin() + 1, f.end(), [](const std::string& c) { return isNumber(c); })) {
      header = true;
      return;
    }
    if (f.size() != 4 && !(f.size() == 3 && z_when_absent))
      throwInputError(path, line,
                      std::string("expected 4 fields 'id,x,y,z'") +
                          (z_when_absent ? " or 3 'id,x,y'" : "") + ", got " +
                          std::to_string(f.size()));
    if (!rows.empty() && f.size() != rows.front().second.size())
      throwInputError(path, line,
                      "expected " + std::to_string(rows.front().second.size()) +
                          " fields like the first row, got " + std::to_string(f.size()));
    rows.emplace_back(line, f);
    if (names) names->see(f[0]);
  });
  std::vector<uwb::Anchor> anchors;
  for (const auto& [line, f] : rows) {
    uwb::Anchor a;
    a.id = names ? (*names)(f[0], path, line, "id") : parseId(f[0], path, line, "id");
    a.position << parseNumber(f[1], path, line, "x"), parseNumber(f[2], path, line, "y"),
        f.size() == 4 ? parseNumber(f[3], path, line, "z") : *z_when_absent;
    if (!a.position.allFinite()) throwInputError(path, line, "anchor coordinates must be finite");
    if (uwb::findAnchor(anchors, a.id))
      throwInputError(
          path, line,
          "duplicate anchor id " + (names ? names->nameOf(a.id) : std::to_string(a.id)));
    anchors.push_back(a);
  }
  if (anchors.empty()) throwInputError(path, 0, "no anchors");
  if (without_z) *without_z = rows.front().second.size() == 3;
  return anchors;
}

std::string formatAnchorsCsv(const std::vector<uwb::Anchor>& anchors) {
  std::ostringstream csv;
  csv << "id,x,y,z\n" << std::fixed << std::setprecision(4);
  for (const auto& a : anchors)
    csv << a.id << ',' << a.position.x() << ',' << a.position.y() << ',' << a.position.z() << '\n';
  return csv.str();
}

std::vector<RangeBias> loadBiasCsv(const std::string& path) {
  std::vector<RangeBias> biases;
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    if (biases.empty() && !f.empty() && f[0] == "anchor_id") return;  // header
    if (f.size() < 3 || f.size() > 6)
      throwInputError(path, line,
                      "expected 'anchor_id,tag_id,bias[,scale[,sigma[,samples]]]', got " +
                          std::to_string(f.size()) + " fields");
    RangeBias b;
    b.anchor_id = parseId(f[0], path, line, "anchor_id");
    if (f[1] != "*") b.tag_id = parseId(f[1], path, line, "tag_id");
    b.bias = parseNumber(f[2], path, line, "bias");
    if (f.size() > 3) b.scale = parseNumber(f[3], path, line, "scale");
    if (f.size() > 4) b.sigma = parseNumber(f[4], path, line, "sigma");
    if (f.size() > 5) b.samples = std::lround(parseNumber(f[5], path, line, "samples"));
    if (!(std::abs(b.bias) < 100.0)) throwInputError(path, line, "bias must be within +-100 m");
    if (!(std::abs(b.scale) < 0.5)) throwInputError(path, line, "scale must be within +-0.5");
    if (!(b.sigma >= 0.0 && b.sigma < 100.0))
      throwInputError(path, line, "sigma must be within 0..100 m");
    for (const auto& o : biases)
      if (o.anchor_id == b.anchor_id && o.tag_id == b.tag_id)
        throwInputError(path, line, "duplicate row for anchor " + f[0] + ", tag " + f[1]);
    biases.push_back(b);
  });
  return biases;
}

std::string formatBiasCsv(const std::vector<RangeBias>& biases) {
  std::string csv = "anchor_id,tag_id,bias,scale,sigma,samples\n";
  char buf[160];
  for (const auto& b : biases) {
    const std::string tag = b.tag_id ? std::to_string(*b.tag_id) : "*";
    std::snprintf(buf, sizeof buf, "%d,%s,%.5f,%.6f,%.5f,%ld\n", b.anchor_id, tag.c_str(), b.bias,
                  b.scale, b.sigma, b.samples);
    csv += buf;
  }
  return csv;
}

const RangeBias* findBias(const std::vector<RangeBias>& biases, int anchor_id, int tag_id) {
  const RangeBias* any = nullptr;
  for (const auto& b : biases) {
    if (b.anchor_id != anchor_id) continue;
    if (b.tag_id == tag_id) return &b;
    if (!b.tag_id) any = &b;
  }
  return any;
}

namespace {

std::string resolvePath(const std::string& value, const std::string& manifest_dir,
                        const std::string& data_dir, const std::string& manifest, int line) {
  if (value.empty()) return value;
  const std::string prefix = "${DATA}/";
  if (value.rfind(prefix, 0) == 0) {
    if (data_dir.empty())
      throwInputError(
          manifest, line,
          "path '" + value + "' needs the data directory: set UWBLOC_DATA_DIR or --data-dir");
    return (fs::path(data_dir) / value.substr(prefix.size())).string();
  }
  const fs::path p(value);
  return p.is_absolute() ? value : (fs::path(manifest_dir) / p).lexically_normal().string();
}

}  // namespace

namespace {

// [anchors]: a CSV and/or MRPT's beacon_NNN_* keys, then the frame transform to the map / GT.
std::vector<uwb::Anchor> readAnchors(const IniFile& ini, const std::string& path,
                                     const std::string& dir, const std::string& data_dir) {
  std::vector<uwb::Anchor> anchors;
  if (const auto csv = ini.get("anchors", "anchors_csv"))
    anchors = loadAnchorsCsv(
        resolvePath(*csv, dir, data_dir, path, ini.lineOf("anchors", "anchors_csv")));
  std::set<std::string> indices;
  for (const auto& key : ini.keys("anchors")) {
    // MRPT's form: beacon_NNN_{ID,X,Y,Z} with a three-digit index.
    if (key.size() > 11 && key.rfind("beacon_", 0) == 0 && key[10] == '_' &&
        std::all_of(key.begin() + 7, key.begin() + 10, [](char c) { return std::isdigit(c); }))
      indices.insert(key.substr(7, 3));
  }
  for (const auto& idx : indices) {
    const std::string base = "beacon_" + idx + "_";
    for (const char* c : {"ID", "X", "Y", "Z"})
      if (!ini.get("anchors", base + c))
        throwInputError(path, ini.lineOf("anchors", base + "ID"),
                        "anchor " + idx + " lacks key '" + base + c + "'");
    uwb::Anchor a;
    a.id = parseId(*ini.get("anchors", base + "ID"), path, ini.lineOf("anchors", base + "ID"),
                   base + "ID");
    a.position << ini.getDouble("anchors", base + "X"), ini.getDouble("anchors", base + "Y"),
        ini.getDouble("anchors", base + "Z");
    if (uwb::findAnchor(anchors, a.id))
      throwInputError(path, ini.lineOf("anchors", base + "ID"),
                      "duplicate anchor id " + std::to_string(a.id));
    anchors.push_back(a);
  }
  if (const auto tf = ini.get("anchors", "gt_origin_in_anchor_frame")) {
    std::istringstream in(*tf);
    double x = 0, y = 0, yaw_deg = 0;
    if (!(in >> x >> y >> yaw_deg))
      throwInputError(path, ini.lineOf("anchors", "gt_origin_in_anchor_frame"),
                      "expected 'x y yaw_deg', got '" + *tf + "'");
    const Eigen::Rotation2Dd rot(yaw_deg * M_PI / 180.0);
    for (auto& a : anchors) {
      const Eigen::Vector2d p = rot.inverse() * (a.position.head<2>() - Eigen::Vector2d(x, y));
      a.position.head<2>() = p;
    }
  }
  if (anchors.empty())
    throwInputError(path, 0, "no anchors: give [anchors] anchors_csv or beacon_NNN_ID/X/Y/Z keys");
  return anchors;
}

// [bounds]: what the Cramér-Rao bounds need.
BoundsSpec readBounds(const IniFile& ini, const std::string& path) {
  BoundsSpec b;
  b.range_sigma = ini.getDouble("bounds", "range_sigma", b.range_sigma);
  b.accel_psd = ini.getDouble("bounds", "accel_psd", b.accel_psd);
  b.motion = ini.getString("bounds", "motion", b.motion);
  if (b.motion != "cv" && b.motion != "odometry")
    throwInputError(path, ini.lineOf("bounds", "motion"), "[bounds] motion must be cv or odometry");
  b.odom_sigma_xy_per_m = ini.getDouble("bounds", "odom_sigma_xy_per_m", b.odom_sigma_xy_per_m);
  b.odom_sigma_theta_per_rad =
      ini.getDouble("bounds", "odom_sigma_theta_per_rad", b.odom_sigma_theta_per_rad);
  b.odom_sigma_theta_per_m =
      ini.getDouble("bounds", "odom_sigma_theta_per_m", b.odom_sigma_theta_per_m);
  if (!(b.range_sigma > 0) || !(b.accel_psd > 0))
    throwInputError(path, ini.lineOf("bounds", "range_sigma"), "[bounds] values must be > 0");
  return b;
}

}  // namespace

Manifest loadManifest(const std::string& path, const std::string& data_dir) {
  const IniFile ini = IniFile::load(path);
  Manifest m;
  m.path = path;
  const std::string dir = fs::path(path).parent_path().string();
  auto pathKey = [&](const char* key) {
    return resolvePath(ini.getString("dataset", key, ""), dir, data_dir, path,
                       ini.lineOf("dataset", key));
  };
  m.name = ini.getString("dataset", "name", fs::path(path).stem().string());
  m.rawlog = pathKey("rawlog");
  if (m.rawlog.empty()) throwInputError(path, 0, "missing key 'rawlog' in section [dataset]");
  m.ground_truth = pathKey("ground_truth");
  m.map = pathKey("map");
  m.gt_max_gap = ini.getDouble("dataset", "gt_max_gap", m.gt_max_gap);
  m.gt_time_offset = ini.getDouble("dataset", "gt_time_offset", 0.0);
  if (!std::isfinite(m.gt_time_offset))
    throwInputError(path, ini.lineOf("dataset", "gt_time_offset"), "gt_time_offset must be finite");
  if (const auto h = ini.get("dataset", "reference_heading")) {
    if (*h != "true" && *h != "false")
      throwInputError(path, ini.lineOf("dataset", "reference_heading"),
                      "reference_heading must be true or false, got '" + *h + "'");
    m.reference_heading = *h == "true";
  }
  m.range_features = pathKey("range_features");
  try {
    m.ground_truth_format = parseGroundTruthFormat(
        ini.getString("dataset", "ground_truth_format", m.ground_truth.empty() ? "none" : ""));
  } catch (const InputError& e) {
    throwInputError(path, ini.lineOf("dataset", "ground_truth_format"), e.what());
  }
  if (!m.ground_truth.empty() && m.ground_truth_format == GroundTruthFormat::kNone)
    throwInputError(path, ini.lineOf("dataset", "ground_truth"),
                    "ground_truth given without ground_truth_format");

  m.anchors = readAnchors(ini, path, dir, data_dir);
  if (const auto tf = ini.get("anchors", "gt_origin_in_anchor_frame")) {
    std::istringstream in(*tf);  // checked by readAnchors
    double x = 0, y = 0, yaw_deg = 0;
    in >> x >> y >> yaw_deg;
    m.gt_origin_in_anchor_frame = Eigen::Vector3d(x, y, yaw_deg * M_PI / 180.0);
  }
  if (const auto bias = ini.get("anchors", "bias_csv")) {
    m.bias_csv = resolvePath(*bias, dir, data_dir, path, ini.lineOf("anchors", "bias_csv"));
    m.biases = loadBiasCsv(m.bias_csv);
  }
  if (ini.get("tag", "height")) m.tag_height = ini.getDouble("tag", "height");
  if (ini.get("tag", "lever_arm_x") || ini.get("tag", "lever_arm_y"))
    m.lever_arm = Eigen::Vector2d(ini.getDouble("tag", "lever_arm_x", 0.0),
                                  ini.getDouble("tag", "lever_arm_y", 0.0));
  for (const auto& key : ini.keys("tag")) {
    if (key.rfind("tag_", 0) != 0) continue;
    const int line = ini.lineOf("tag", key);
    const int id = parseId(key.substr(4), path, line, "[tag] " + key);
    std::istringstream in(*ini.get("tag", key));
    Eigen::Vector3d p;
    std::string extra;
    if (!(in >> p.x() >> p.y() >> p.z()) || (in >> extra) || !p.allFinite())
      throwInputError(path, line, "[tag] " + key + ": expected 'x y z' (position on the robot, m)");
    m.tags[id] = p;
  }
  if (!m.tags.empty() && (m.tag_height || m.lever_arm))
    throwInputError(path, ini.lineOf("tag", "height"),
                    "[tag]: give either tag_<id> keys or height/lever_arm_x/lever_arm_y, not both");
  if (ini.get("uwb", "sigma")) {
    m.uwb_sigma = ini.getDouble("uwb", "sigma");
    if (!(*m.uwb_sigma > 0))
      throwInputError(path, ini.lineOf("uwb", "sigma"), "[uwb] sigma must be > 0");
  }
  if (ini.hasSection("bounds")) m.bounds = readBounds(ini, path);
  ini.rejectUnread();
  return m;
}

}  // namespace uwbloc::data
