#include "uwbloc/dataset/lias_import.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

constexpr int kAnchors = 8;
constexpr int kTags = 3;

// Days from 1970-01-01 to y-m-d (proleptic Gregorian).
long daysFromCivil(long y, unsigned m, unsigned d) {
  y -= m <= 2;
  const long era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<long>(doe) - 719468;
}

// The coordinates a README's tables give.
struct Setup {
  std::map<int, Eigen::Vector3d> tags;                ///< tag index -> local coordinates
  std::vector<uwb::Anchor> anchors;                   ///< in the global frame
  std::map<int, std::vector<Eigen::Vector3d>> poses;  ///< pose k -> (yaw_deg, x, y) rows
};

std::vector<std::string> tableCells(const std::string& line) {
  std::vector<std::string> cells;
  size_t start = line.find('|');
  while (start != std::string::npos) {
    const size_t end = line.find('|', start + 1);
    if (end == std::string::npos) break;
    std::string c = line.substr(start + 1, end - start - 1);
    const auto b = c.find_first_not_of(" \t");
    const auto e = c.find_last_not_of(" \t");
    cells.push_back(b == std::string::npos ? "" : c.substr(b, e - b + 1));
    start = end;
  }
  return cells;
}

std::optional<double> number(const std::string& s) {
  if (s.empty()) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

// Reads the "Tag k", "Anchor k" and "Pose k" rows of a README, within the "### ..." section whose
// title ends with `section` (the whole file when empty).
Setup readSetup(const std::string& path, const std::string& section) {
  requireRegularFile(path);
  std::ifstream in(path);
  Setup s;
  std::string line;
  bool inside = section.empty();
  int pose = -1;
  static const std::regex name(R"((Tag|Anchor|Pose)\s+(\d+))");
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!section.empty() && line.rfind("### ", 0) == 0) {
      inside = line.size() >= section.size() &&
               line.compare(line.size() - section.size(), section.size(), section) == 0;
      pose = -1;
      continue;
    }
    if (!inside || line.find('|') == std::string::npos) continue;
    const auto cells = tableCells(line);
    if (cells.size() < 4) continue;
    std::vector<double> v;
    for (size_t i = 1; i < 4; ++i)
      if (const auto x = number(cells[i])) v.push_back(*x);
    std::smatch m;
    if (std::regex_match(cells[0], m, name)) {
      const int k = parseId(m[2].str(), path, line_no, m[1].str() + " number");
      const std::string kind = m[1].str();
      if (kind == "Pose") {
        pose = k;
        if (v.size() == 3) s.poses[pose].emplace_back(v[0], v[1], v[2]);
        continue;
      }
      pose = -1;
      if (v.size() != 3) continue;
      if (kind == "Tag")
        s.tags[k] = Eigen::Vector3d(v[0], v[1], v[2]);
      else
        s.anchors.push_back({k, Eigen::Vector3d(v[0], v[1], v[2])});
    } else if (cells[0].empty() && pose >= 0 && v.size() == 3) {
      s.poses[pose].emplace_back(v[0], v[1], v[2]);
    }
  }
  return s;
}

// The README that holds the coordinates: <root>/Planar_Dataset/<kind>/README.md, searched in
// the UWB file's folder and up to three folders above it.
std::string findReadme(const std::string& uwb_file, const std::string& kind) {
  fs::path dir = fs::absolute(uwb_file).parent_path();
  for (int up = 0; up < 4 && !dir.empty(); ++up, dir = dir.parent_path()) {
    const fs::path p = dir / "Planar_Dataset" / kind / "README.md";
    std::error_code ec;
    if (fs::is_regular_file(p, ec)) return p.string();
  }
  throwInputError(uwb_file, 0,
                  "no Planar_Dataset/" + kind +
                      "/README.md above this file (the anchor and tag coordinates); give --readme");
  return {};
}

struct UwbRow {
  double t = 0.0;
  std::array<double, kAnchors * kTags> ranges{};  ///< NaN: empty or unusable
};

std::vector<UwbRow> readUwb(const std::string& path, ImportSummary& summary) {
  std::vector<UwbRow> rows;
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    const auto t = parseDateTime(f[0]);
    if (!t)
      throwInputError(path, line,
                      "field 1: expected a time 'YYYY-MM-DD H:MM:SS.fff', got '" + f[0] + "'");
    // Trailing empty fields (some static files end each row with ",,,,,,,,,") are no data.
    size_t n = f.size();
    while (n > 1 && f[n - 1].empty()) --n;
    // Corrupt rows seen in the recordings: a row short of one anchor's three ranges (the others
    // shifted left, so no column can be trusted), and rows with junk values after the 24th.
    if (n < 1 + kAnchors * kTags) {
      if (summary.skipped["uwb_row_short"]++ == 0)
        summary.notes.push_back(path + ":" + std::to_string(line) + ": first row with " +
                                std::to_string(n - 1) + " of 24 ranges (skipped, counted)");
      return;
    }
    if (n > 1 + kAnchors * kTags) ++summary.skipped["uwb_row_extra_values_ignored"];
    UwbRow row;
    row.t = *t;
    if (!rows.empty() && row.t < rows.back().t) return void(++summary.skipped["uwb_out_of_order"]);
    for (int k = 0; k < kAnchors * kTags; ++k) {
      const auto v = number(f[static_cast<size_t>(k + 1)]);
      row.ranges[static_cast<size_t>(k)] = v && *v > 0.0 ? *v : NAN;
      if (!v)
        ++summary.skipped["range_not_a_number"];
      else if (!(*v > 0.0))
        ++summary.skipped["range_zero_or_negative"];
    }
    rows.push_back(row);
  });
  if (rows.empty()) throwInputError(path, 0, "no UWB rows");
  return rows;
}

// Motion capture: time, centroid, and the quaternion's yaw (ZYX) with the body's z axis sign.
struct MocapRow {
  double t = 0.0;
  Eigen::Vector3d p;
  double yaw = 0.0;
};

std::vector<MocapRow> readMocap(const std::string& path, ImportSummary& summary) {
  std::vector<MocapRow> rows;
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    if (f[0] == "time") return;  // header
    const auto t = parseDateTime(f[0]);
    if (!t || f.size() < 8) throwInputError(path, line, "expected 'time,x,y,z,qw,qx,qy,qz'");
    double v[7];
    for (int i = 0; i < 7; ++i) {
      const auto x = number(f[static_cast<size_t>(i + 1)]);
      if (!x) return void(++summary.skipped["mocap_not_a_number"]);
      v[i] = *x;
    }
    const double norm = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (std::abs(norm - 1.0) > 0.05) return void(++summary.skipped["mocap_bad_quaternion"]);
    if (!rows.empty() && *t <= rows.back().t)
      return void(++summary.skipped["mocap_time_not_increasing"]);
    const Eigen::Quaterniond q(v[3] / norm, v[4] / norm, v[5] / norm, v[6] / norm);
    const Eigen::Matrix3d r = q.toRotationMatrix();
    rows.push_back({*t, Eigen::Vector3d(v[0], v[1], v[2]), std::atan2(r(1, 0), r(0, 0))});
  });
  if (rows.size() < 2) throwInputError(path, 0, "fewer than two usable motion-capture rows");
  return rows;
}

// One reading of the motion capture's orientation: heading = sign * yaw, and each tag's lever
// arm with y mirrored (a body frame flipped about x) or not.
struct Convention {
  double yaw_sign = 1.0;
  double y_sign = 1.0;
  double offset = 0.0;      ///< reference time = UWB time + offset [s]
  double yaw_offset = 0.0;  ///< robot heading = yaw_sign * yaw + yaw_offset [rad]
  double median_residual = INFINITY;
};

std::optional<Eigen::Vector3d> poseAt(const std::vector<MocapRow>& m, double t, double yaw_sign,
                                      double yaw_offset) {
  auto hi =
      std::lower_bound(m.begin(), m.end(), t, [](const MocapRow& r, double v) { return r.t < v; });
  if (hi == m.begin() || hi == m.end()) return std::nullopt;
  const auto lo = hi - 1;
  if (hi->t - lo->t > 0.1) return std::nullopt;
  const double a = (t - lo->t) / (hi->t - lo->t);
  const Eigen::Vector3d p = lo->p + a * (hi->p - lo->p);
  const double yaw = lo->yaw + a * wrapAngle(hi->yaw - lo->yaw);
  return Eigen::Vector3d(p.x(), p.y(), wrapAngle(yaw_sign * yaw + yaw_offset));
}

double medianResidual(const std::vector<UwbRow>& uwb, const std::vector<MocapRow>& mocap,
                      const Setup& setup, const Convention& c, double height, size_t stride) {
  // Each link's residuals are taken about their median: the links' constant biases (tens of
  // centimetres here) would otherwise blur the comparison.
  std::array<std::vector<double>, kAnchors * kTags> link;
  for (size_t i = 0; i < uwb.size(); i += stride) {
    const auto pose = poseAt(mocap, uwb[i].t + c.offset, c.yaw_sign, c.yaw_offset);
    if (!pose) continue;
    for (int k = 0; k < kAnchors * kTags; ++k) {
      const double r = uwb[i].ranges[static_cast<size_t>(k)];
      const auto tag = setup.tags.find(k % kTags);
      if (!std::isfinite(r) || tag == setup.tags.end()) continue;
      const uwb::Anchor* a = uwb::findAnchor(setup.anchors, k / kTags);
      const Eigen::Vector3d lever(tag->second.x(), c.y_sign * tag->second.y(), height);
      link[static_cast<size_t>(k)].push_back(r - uwb::predictRange(*pose, lever, a->position));
    }
  }
  std::vector<double> res;
  for (auto& v : link) {
    if (v.empty()) continue;
    auto mid = v.begin() + static_cast<long>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    const double m = *mid;
    for (double x : v) res.push_back(std::abs(x - m));
  }
  if (res.size() < 10) return INFINITY;
  auto mid = res.begin() + static_cast<long>(res.size() / 2);
  std::nth_element(res.begin(), mid, res.end());
  return *mid;
}

// The convention and clock offset with the smallest median residual: a coarse offset grid over
// +-2 s for each convention, then a fine one around the best; then the best convention's
// constant heading offset (the motion capture's body axes need not be the tags' frame) on a
// grid over +-30 degrees.
Convention chooseConvention(const std::vector<UwbRow>& uwb, const std::vector<MocapRow>& mocap,
                            const Setup& setup, double height, std::vector<Convention>* all) {
  Convention best;
  const size_t stride = std::max<size_t>(1, uwb.size() / 1500);
  for (double ys : {1.0, -1.0})
    for (double ms : {1.0, -1.0}) {
      Convention c{ys, ms, 0.0, 0.0, INFINITY};
      for (double off = -2.0; off <= 2.0 + 1e-9; off += 0.02) {
        Convention t{ys, ms, off, 0.0, 0.0};
        t.median_residual = medianResidual(uwb, mocap, setup, t, height, stride);
        if (t.median_residual < c.median_residual) c = t;
      }
      for (double off = c.offset - 0.02; off <= c.offset + 0.02 + 1e-9; off += 0.002) {
        Convention t{ys, ms, off, 0.0, 0.0};
        t.median_residual = medianResidual(uwb, mocap, setup, t, height, stride);
        if (t.median_residual < c.median_residual) c = t;
      }
      all->push_back(c);
      if (c.median_residual < best.median_residual) best = c;
    }
  const Convention start = best;
  for (double deg = -30.0; deg <= 30.0 + 1e-9; deg += 0.5) {
    Convention t = start;
    t.yaw_offset = deg * M_PI / 180.0;
    t.median_residual = medianResidual(uwb, mocap, setup, t, height, stride);
    if (t.median_residual < best.median_residual) best = t;
  }
  return best;
}

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// What a static run takes from the dynamic run beside it: the tags' height (the motion
// capture's median z) and, when the run's ranges are there too, the convention chooseConvention
// finds for it (the static README's yaw is the same motion capture's).
struct DynamicFrame {
  double height = 0.0;
  std::optional<Convention> conv;
  std::string source;  ///< the file the convention was found on, or why there is none
};

// The motion capture's file for a dynamic run's UWB file: motion_capture_<rest> beside it.
std::string mocapFileFor(const std::string& uwb_file) {
  const std::string name = fs::path(uwb_file).filename().string();
  if (name.rfind("UWB_", 0) != 0)
    throwInputError(uwb_file, 0, "a dynamic run's file name starts with 'UWB_'");
  return (fs::path(uwb_file).parent_path() / ("motion_capture_" + name.substr(4))).string();
}

struct StaticName {
  std::string section;  ///< "/8/14"
  int pose = 0;
  double deg = 0.0;
};

std::optional<StaticName> parseStaticName(const std::string& file) {
  static const std::regex re(R"(UWB_static_exp_(\d+)_(\d+)_pos(\d+)_deg_(\d+)\.csv)");
  std::smatch m;
  const std::string name = fs::path(file).filename().string();
  if (!std::regex_match(name, m, re)) return std::nullopt;
  // The numbers are digits only (the pattern), but may be too long for an int.
  return StaticName{"/" + m[1].str() + "/" + m[2].str(), parseId(m[3].str(), file, 0, "pos"),
                    parseNumber(m[4].str(), file, 0, "deg")};
}

// The README's setup must hold tags 0-2 and anchors 0-7, once each (a row's 24 ranges are anchor
// k / 3 to tag k % 3); `section` is the static README's "/<month>/<day>", empty for the dynamic.
void requireFullSetup(const Setup& setup, const std::string& readme, const std::string& section) {
  if (setup.tags.size() != kTags || setup.anchors.size() != kAnchors)
    throwInputError(readme, 0,
                    "expected the coordinates of 3 tags and 8 anchors" +
                        (section.empty() ? std::string()
                                         : " under a '### .../" + section.substr(1) + "' heading") +
                        ", found " + std::to_string(setup.tags.size()) + " and " +
                        std::to_string(setup.anchors.size()));
  // A row's 24 ranges are anchor k / 3 to tag k % 3: the numbers must be 0-2 and 0-7, once each.
  std::string ids;
  for (const auto& a : setup.anchors) ids += " " + std::to_string(a.id);
  for (int k = 0; k < kAnchors; ++k)
    if (std::count_if(setup.anchors.begin(), setup.anchors.end(),
                      [k](const uwb::Anchor& a) { return a.id == k; }) != 1)
      throwInputError(readme, 0, "expected anchors numbered 0 to 7, once each; found" + ids);
  for (int k = 0; k < kTags; ++k)
    if (!setup.tags.count(k)) throwInputError(readme, 0, "expected tags numbered 0 to 2");
}

// The frame of the dynamic runs beside a static run (<root>/Dynamic): the height from the first
// motion capture by name, the convention from the first UWB_dynamic_exp_*.csv that has its motion
// capture. Nothing when there is no motion capture; a dynamic run that cannot be read leaves the
// convention out and says why.
std::optional<DynamicFrame> dynamicRunFrame(const std::string& static_file) {
  const fs::path dir = fs::absolute(static_file).parent_path().parent_path() / "Dynamic";
  std::vector<std::string> runs, captures;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string n = e.path().filename().string();
    if (n.rfind("motion_capture_", 0) == 0) captures.push_back(e.path().string());
    if (n.rfind("UWB_dynamic_exp_", 0) == 0 &&
        fs::is_regular_file(mocapFileFor(e.path().string()), ec))
      runs.push_back(e.path().string());
  }
  if (captures.empty()) return std::nullopt;
  std::sort(captures.begin(), captures.end());
  std::sort(runs.begin(), runs.end());
  DynamicFrame f;
  ImportSummary ignored;
  const std::string capture = runs.empty() ? captures.front() : mocapFileFor(runs.front());
  const auto mocap = readMocap(capture, ignored);
  std::vector<double> z;
  for (const auto& r : mocap) z.push_back(r.p.z());
  f.height = median(z);
  if (runs.empty()) {
    f.source = "no dynamic run's ranges beside to find the motion capture's frame on";
    return f;
  }
  try {
    const std::string readme = findReadme(runs.front(), "Dynamic");
    const Setup setup = readSetup(readme, "");
    requireFullSetup(setup, readme, "");
    const auto uwb = readUwb(runs.front(), ignored);
    std::vector<Convention> all;
    const Convention c = chooseConvention(uwb, mocap, setup, f.height, &all);
    if (std::isfinite(c.median_residual)) f.conv = c;
    f.source =
        f.conv
            ? "the motion capture's frame found on " + fs::path(runs.front()).filename().string()
            : fs::path(runs.front()).filename().string() + " does not overlap its motion capture";
  } catch (const InputError& e) {
    f.source = std::string("the dynamic run beside could not be read: ") + e.what();
  }
  return f;
}

}  // namespace

std::optional<double> parseDateTime(const std::string& text) {
  static const std::regex re(R"((\d{4})-(\d{1,2})-(\d{1,2})[ T](\d{1,2}):(\d{2}):(\d{2}(\.\d+)?))");
  std::smatch m;
  if (!std::regex_match(text, m, re)) return std::nullopt;
  const long y = std::stol(m[1].str());
  const auto mo = static_cast<unsigned>(std::stoul(m[2].str()));
  const auto d = static_cast<unsigned>(std::stoul(m[3].str()));
  const long h = std::stol(m[4].str()), mi = std::stol(m[5].str());
  const double s = std::stod(m[6].str());
  if (mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || s >= 61.0) return std::nullopt;
  return static_cast<double>(daysFromCivil(y, mo, d)) * 86400.0 +
         static_cast<double>(h * 3600 + mi * 60) + s;
}

ImportSummary importLias(const std::string& uwb_file, const std::string& out_dir,
                         const LiasImportParams& params) {
  ImportSummary summary;
  const auto static_name = parseStaticName(uwb_file);
  const std::string kind = static_name ? "Static" : "Dynamic";
  const std::string readme = params.readme.empty() ? findReadme(uwb_file, kind) : params.readme;
  const Setup setup = readSetup(readme, static_name ? static_name->section : "");
  requireFullSetup(setup, readme, static_name ? static_name->section : "");
  const std::vector<UwbRow> uwb = readUwb(uwb_file, summary);

  std::vector<TimedPose> reference;
  Convention conv;
  double height = 0.0;
  ManifestDraft m;
  m.comments.push_back("Imported by 'uwbloc import lias' from " + fs::absolute(uwb_file).string());
  m.comments.push_back("Anchor and tag coordinates from " + fs::absolute(readme).string());
  char buf[400];
  if (!static_name) {
    const std::string mocap_file = mocapFileFor(uwb_file);
    const auto mocap = readMocap(mocap_file, summary);
    std::vector<double> z;
    for (const auto& r : mocap) z.push_back(r.p.z());
    height = params.tag_height.value_or(median(z));
    std::vector<Convention> all;
    conv = chooseConvention(uwb, mocap, setup, height, &all);
    if (!std::isfinite(conv.median_residual))
      throwInputError(mocap_file, 0, "the motion capture does not overlap the UWB ranges");
    for (const auto& c : all) {
      std::snprintf(buf, sizeof buf,
                    "Orientation reading heading %+g x yaw, lever arm y %+g: median |range "
                    "residual about its link's median| %.3f m at clock offset %+.3f s",
                    c.yaw_sign, c.y_sign, c.median_residual, c.offset);
      summary.notes.emplace_back(buf);
    }
    std::snprintf(buf, sizeof buf,
                  "Chosen: heading %+g x the motion capture's yaw %+.1f deg, tags' lever arm y "
                  "taken %s, reference time = UWB time %+.3f s (median |range residual about "
                  "its link's median| %.3f m); tag height %.3f m (%s)",
                  conv.yaw_sign, conv.yaw_offset * 180.0 / M_PI,
                  conv.y_sign > 0 ? "as given" : "mirrored", conv.offset, conv.median_residual,
                  height, params.tag_height ? "given" : "median z of the motion capture");
    summary.notes.emplace_back(buf);
    m.comments.emplace_back(buf);
    for (const auto& r : mocap)
      reference.push_back(
          {r.t - conv.offset,
           Eigen::Vector3d(r.p.x(), r.p.y(), wrapAngle(conv.yaw_sign * r.yaw + conv.yaw_offset))});
  } else {
    const auto it = setup.poses.find(static_name->pose);
    if (it == setup.poses.end())
      throwInputError(readme, 0, "no 'Pose " + std::to_string(static_name->pose) + "' table rows");
    const Eigen::Vector3d* row = nullptr;
    for (const auto& p : it->second)
      if (std::abs(wrapAngle((p.x() - static_name->deg) * M_PI / 180.0)) < M_PI / 6 &&
          (!row || std::abs(p.x() - static_name->deg) < std::abs(row->x() - static_name->deg)))
        row = &p;
    if (!row)
      throwInputError(readme, 0,
                      "pose " + std::to_string(static_name->pose) + " has no row near " +
                          std::to_string(static_name->deg) + " degrees");
    // The README's yaw is the motion capture's; the dynamic run beside says how that maps to the
    // tags' frame (on the shared copy: +6 degrees), unless --yaw-offset gives it.
    std::optional<DynamicFrame> frame;
    if (!params.tag_height || !params.yaw_offset_deg) frame = dynamicRunFrame(uwb_file);
    if (params.tag_height) {
      height = *params.tag_height;
    } else if (frame) {
      height = frame->height;
    } else {
      throwInputError(uwb_file, 0,
                      "a static run's tag height is not in its README: give --tag-height, or "
                      "keep the Dynamic folder (its motion capture) beside Static");
    }
    std::string heading_from;
    if (params.yaw_offset_deg) {
      conv.yaw_offset = *params.yaw_offset_deg * M_PI / 180.0;
      heading_from = "--yaw-offset";
    } else if (frame && frame->conv) {
      conv = *frame->conv;
      heading_from = frame->source;
    } else {
      heading_from =
          "unchecked: " + (frame ? frame->source : std::string("no dynamic run beside")) +
          "; give --yaw-offset";
    }
    const Eigen::Vector3d pose(
        row->y(), row->z(), wrapAngle(conv.yaw_sign * row->x() * M_PI / 180.0 + conv.yaw_offset));
    reference.push_back({uwb.front().t, pose});
    reference.push_back({uwb.back().t, pose});
    m.gt_max_gap = uwb.back().t - uwb.front().t + 1.0;
    std::snprintf(buf, sizeof buf,
                  "Static pose %d at %g deg: x %.4f y %.4f yaw %.3f deg (README), heading %.3f "
                  "deg = %+g x yaw %+.1f deg, tags' lever arm y taken %s; tag height %.3f m (%s)",
                  static_name->pose, static_name->deg, pose.x(), pose.y(), row->x(),
                  pose.z() * 180.0 / M_PI, conv.yaw_sign, conv.yaw_offset * 180.0 / M_PI,
                  conv.y_sign > 0 ? "as given" : "mirrored", height,
                  params.tag_height ? "given" : "median z of the dynamic run's motion capture");
    const std::string note = std::string(buf) + "; heading: " + heading_from;
    summary.notes.push_back(note);
    m.comments.push_back(note);
  }

  std::vector<loc::Event> events;
  events.reserve(uwb.size() * kAnchors * kTags);
  long quantised = 0, ranges = 0;
  for (const auto& row : uwb)
    for (int tag = 0; tag < kTags; ++tag)
      for (int a = 0; a < kAnchors; ++a) {
        const double r = row.ranges[static_cast<size_t>(a * kTags + tag)];
        if (!std::isfinite(r)) continue;
        uwb::Range range;
        range.t = row.t;
        range.anchor_id = a;
        range.tag_id = tag;
        range.on_robot = true;
        range.range = r;
        const Eigen::Vector3d& l = setup.tags.at(tag);
        range.tag_on_robot = Eigen::Vector3d(l.x(), conv.y_sign * l.y(), height);
        events.emplace_back(range);
        ++ranges;
        quantised += std::abs(r * 100.0 - std::round(r * 100.0)) < 1e-6;
      }
  if (ranges > 0 && quantised > 0.99 * static_cast<double>(ranges))
    summary.notes.emplace_back(
        "The ranges are quantised to 1 cm (a 0.29 cm rounding noise, well below the ranging "
        "noise)");

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "uwb.rawlog").string(), events);
  writeFileAtomic((out / "ground_truth.tum").string(), formatTum(reference));
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(setup.anchors));
  if (!params.bias_csv.empty()) {
    const auto biases = loadBiasCsv(params.bias_csv);
    writeFileAtomic((out / "bias.csv").string(), formatBiasCsv(biases));
    m.bias_csv = "bias.csv";
    summary.notes.push_back("Range biases from " + params.bias_csv + " (" +
                            std::to_string(biases.size()) + " rows) named in the manifest");
  }
  m.name = "lias_" + fs::path(uwb_file).stem().string();
  m.rawlog = "uwb.rawlog";
  m.ground_truth = "ground_truth.tum";
  m.ground_truth_format = GroundTruthFormat::kTum;
  m.anchors_csv = "anchors.csv";
  for (const auto& [id, l] : setup.tags)
    m.tags[id] = Eigen::Vector3d(l.x(), conv.y_sign * l.y(), height);
  summary.manifest = writeManifest(out_dir, m);
  summary.ranges = ranges;
  summary.anchors = kAnchors;
  summary.ground_truth_rows = static_cast<long>(reference.size());
  return summary;
}

}  // namespace uwbloc::data
