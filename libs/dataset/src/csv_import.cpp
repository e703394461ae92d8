#include "uwbloc/dataset/csv_import.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>

#include "odometry_poses.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/odometry_check.hpp"
#include "uwbloc/dataset/range_geometry.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/tag_fit.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/params.hpp"
#include "uwbloc/localization/range_noise.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// A header's column name in lower case, without a unit in brackets after it: "Range [m]" and
// "time (s)" name the columns range and time.
std::string headerName(const std::string& text) {
  std::string name = lower(text);
  if (!name.empty() && (name.back() == ']' || name.back() == ')')) {
    const auto open = name.find_last_of(name.back() == ']' ? '[' : '(');
    if (open != std::string::npos && open > 0) name.erase(open);
  }
  while (!name.empty() && (name.back() == ' ' || name.back() == '_')) name.pop_back();
  return name;
}

// Column positions from a header row: the first of `names` found, or -1.
int column(const std::vector<std::string>& header, std::initializer_list<const char*> names) {
  for (const char* n : names)
    for (size_t i = 0; i < header.size(); ++i)
      if (headerName(header[i]) == n) return static_cast<int>(i);
  return -1;
}

// Rows of a CSV file, its header (when the first row is not numeric) apart.
struct Table {
  std::vector<std::string> header;
  std::vector<std::pair<int, std::vector<std::string>>> rows;  ///< (line, fields)
};

Table readTable(const std::string& path) {
  Table t;
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    if (t.rows.empty() && t.header.empty() && !f.empty() && !isNumber(f[0])) {
      t.header = f;
      return;
    }
    t.rows.emplace_back(line, f);
  });
  if (t.rows.empty()) throwInputError(path, 0, "no data rows");
  return t;
}

// The finite numbers in column `col` of the rows (a field that does not parse is left to the
// reader, which names its line).
std::vector<double> columnValues(const Table& table, size_t col) {
  std::vector<double> v;
  for (const auto& row : table.rows) {
    if (col >= row.second.size()) continue;
    const std::string& text = row.second[col];
    if (!isNumber(text)) continue;
    const double x = std::strtod(text.c_str(), nullptr);
    if (std::isfinite(x)) v.push_back(x);
  }
  return v;
}

// Seconds per unit of the time column `col` of `path` (CsvImportRequest::time_unit).
double timeScale(const Table& table, size_t col, const std::string& unit, const std::string& path,
                 ImportSummary& s) {
  if (unit != "auto") return secondsPerTimeUnit(unit);
  const auto times = columnValues(table, col);
  if (times.empty()) return 1.0;
  const double median = loc::medianOf(times);
  if (!(median > kLatestTimestamp)) return 1.0;
  static const std::pair<const char*, double> kUnits[] = {
      {"milliseconds", 1e-3}, {"microseconds", 1e-6}, {"nanoseconds", 1e-9}};
  for (const auto& [name, scale] : kUnits) {
    if (median * scale > kLatestTimestamp) continue;
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "WARNING: %s: times read as %s: in seconds their median, %.6g, is after the "
                  "year 3000 (--time-unit sets the unit)",
                  path.c_str(), name, median);
    s.notes.emplace_back(buf);
    return scale;
  }
  return 1.0;  // beyond nanoseconds too: refused row by row
}

// [m] Beyond any UWB link's reach (a few hundred metres at most, line of sight, lowest data
// rate): a median range longer is in another unit.
constexpr double kFarthestRange = 1000.0;

// Metres per unit of a length unit's name (m, cm, mm, in, ft); throws InputError naming
// `option` for another.
double metresPerUnit(const std::string& unit, const char* option) {
  if (unit == "m") return 1.0;
  for (const auto& u : kAnchorUnits)
    if (unit == u.symbol) return u.metres;
  throw InputError(std::string("import csv: ") + option +
                   " must be auto, m, cm, mm, in or ft, got '" + unit + "'");
}

// Metres per unit of the ranges `values` of `path` (CsvImportRequest::range_unit).
double rangeScale(const std::vector<double>& values, const std::vector<uwb::Anchor>& anchors,
                  const std::string& unit, const std::string& path, ImportSummary& s) {
  if (unit != "auto") return metresPerUnit(unit, "--range-unit");
  if (values.empty()) return 1.0;
  double spacing = 0.0;
  for (size_t i = 0; i < anchors.size(); ++i)
    for (size_t j = i + 1; j < anchors.size(); ++j)
      spacing = std::max(spacing, (anchors[i].position - anchors[j].position).norm());
  const double median = loc::medianOf(values);
  char buf[400];
  if (!(median > std::max(10.0 * spacing, 100.0))) {
    if (!(median > kFarthestRange)) return 1.0;
    // Among anchors as far apart, but beyond any UWB link: both in millimetres or centimetres.
    std::snprintf(buf, sizeof buf,
                  "the ranges' median, %.6g, is beyond any UWB link's reach as metres (%.0f m), "
                  "and the anchors span %.6g: if both are in millimetres or centimetres, give "
                  "--range-unit and --anchor-unit (m takes them as written)",
                  median, kFarthestRange, spacing);
    throwInputError(path, 0, buf);
  }
  // The readings that put the tag among the anchors: a median range between a tenth of and 3
  // times their largest spacing.
  std::vector<LengthUnit> fits;
  for (const auto& u : kRangeUnits)
    if (median * u.metres >= 0.1 * spacing && median * u.metres <= std::max(3.0 * spacing, 3.0))
      fits.push_back(u);
  if (fits.size() != 1) {
    std::snprintf(buf, sizeof buf,
                  "the ranges' median, %.6g, is over 10 times the anchors' largest spacing "
                  "(%.3g m) and over 100 m, so not metres, and %s: give --range-unit m, cm or mm",
                  median, spacing,
                  fits.empty() ? "neither centimetres nor millimetres put the tag among the anchors"
                               : "both centimetres and millimetres would put the tag among them");
    throwInputError(path, 0, buf);
  }
  std::snprintf(buf, sizeof buf,
                "WARNING: %s: ranges read as %s: in metres their median, %.6g m, is over 10 times "
                "the anchors' largest spacing (%.3g m) and over 100 m (--range-unit sets the unit)",
                path.c_str(), fits.front().name, median, spacing);
  s.notes.emplace_back(buf);
  return fits.front().metres;
}

// The time of a row in seconds (the column's value times `scale`), or nothing (counted) when it
// cannot be used.
std::optional<double> rowTime(const std::string& text, const std::string& path, int line,
                              const std::string& what, ImportSummary& s, double scale) {
  const double t = parseNumber(text, path, line, "t") * scale;
  if (const char* problem = timestampProblem(t)) {
    ++s.skipped[what + "_" + problem];
    return std::nullopt;
  }
  return t;
}

constexpr std::initializer_list<const char*> kTimeNames = {"t", "time", "timestamp", "stamp"},
                                             kAnchorNames = {"anchor_id", "anchor", "beacon_id",
                                                             "beacon"},
                                             kRangeNames = {"range", "distance"},
                                             kTagNames = {"tag_id", "tag"};

// The anchor that a column of a ranges file written one column per anchor holds: its header
// names an id of the anchors file (`anchor_names`, matched without case), alone or after a word
// and a separator ("range_A3", "d1", "dist-2", "Anchor 4"), a unit in brackets after it
// ignored. nullopt for a column of something else: a word that names a quality rather than a
// distance ("rssi1", "std_2"), or no anchor.
std::optional<std::string> anchorOfColumn(const std::string& header,
                                          const std::vector<std::string>& anchor_names) {
  const std::string name = headerName(header);
  for (const auto& a : anchor_names)
    if (lower(a) == name) return a;
  size_t word = 0;
  while (word < name.size() && std::isalpha(static_cast<unsigned char>(name[word]))) ++word;
  if (word == 0 || word == name.size()) return std::nullopt;
  static const std::set<std::string> kNotDistances = {
      "rssi", "rx",    "fp", "power", "snr", "quality", "nlos",  "los",    "std", "sigma", "var",
      "err",  "error", "x",  "y",     "z",   "seq",     "count", "status", "id",  "cir"};
  if (kNotDistances.count(name.substr(0, word))) return std::nullopt;
  std::string rest = name.substr(word);
  if (rest.front() == '_' || rest.front() == '-' || rest.front() == ' ' || rest.front() == '.')
    rest.erase(0, 1);
  for (const auto& a : anchor_names)
    if (lower(a) == rest) return a;
  return std::nullopt;
}

// A ranges file written one column per anchor, a row per epoch (`t,A1,A2,A3`: a logger's or a
// spreadsheet's layout), as the table of one range a row that the reader takes
// (`t,anchor_id,range[,tag_id]`, each row keeping its line). `anchor_names` are the anchors
// file's ids as written. An empty cell, NaN, or a reading at or below zero is no range (counted:
// range_empty_cell, range_not_positive_cell); columns that name no anchor are left out, said.
// Returns `table` unchanged when it names an anchor and a range column (or has no header).
Table rangesOneAnAnchorRow(const Table& table, const std::vector<std::string>& anchor_names,
                           const std::string& path, ImportSummary& s) {
  if (table.header.empty() || column(table.header, kAnchorNames) >= 0 ||
      column(table.header, kRangeNames) >= 0)
    return table;
  const int ct = column(table.header, kTimeNames), ctag = column(table.header, kTagNames);
  if (ct < 0) return table;                             // the reader names what the header lacks
  std::vector<std::pair<size_t, std::string>> columns;  // (column, anchor)
  std::vector<std::string> left_out;
  for (size_t i = 0; i < table.header.size(); ++i) {
    if (static_cast<int>(i) == ct || static_cast<int>(i) == ctag) continue;
    const auto anchor = anchorOfColumn(table.header[i], anchor_names);
    if (!anchor) {
      left_out.push_back(loc::quoteToken(table.header[i]));
      continue;
    }
    for (const auto& [other, a] : columns)
      if (a == *anchor)
        throwInputError(path, 1,
                        "columns " + loc::quoteToken(table.header[other]) + " and " +
                            loc::quoteToken(table.header[i]) + " both name anchor " + a);
    columns.emplace_back(i, *anchor);
  }
  if (columns.empty()) {
    std::string ids;
    for (const auto& a : anchor_names) ids += (ids.empty() ? "" : ", ") + a;
    throwInputError(path, 1,
                    "the header must name the columns t, anchor_id and range, or t and one "
                    "column per anchor of the anchors file (" +
                        ids + ")");
  }
  Table long_table;
  long_table.header = {"t", "anchor_id", "range"};
  if (ctag >= 0) long_table.header.emplace_back("tag_id");
  for (const auto& [line, f] : table.rows) {
    if (f.size() != table.header.size())
      throwInputError(path, line,
                      "expected " + std::to_string(table.header.size()) +
                          " fields like the header, got " + std::to_string(f.size()));
    for (const auto& [i, anchor] : columns) {
      const std::string& cell = f[i];
      const std::string l = lower(cell);
      if (l.empty() || l == "nan" || l == "-nan" || l == "na" || l == "n/a" || l == "-" ||
          l == "null" || l == "none") {
        ++s.skipped["range_empty_cell"];
        continue;
      }
      if (isNumber(cell) && !(std::strtod(cell.c_str(), nullptr) > 0.0)) {
        ++s.skipped["range_not_positive_cell"];
        continue;
      }
      std::vector<std::string> row = {f[static_cast<size_t>(ct)], anchor, cell};
      if (ctag >= 0) row.push_back(f[static_cast<size_t>(ctag)]);
      long_table.rows.emplace_back(line, std::move(row));
    }
  }
  std::string said = "The ranges are written one column per anchor: ";
  for (size_t k = 0; k < columns.size(); ++k)
    said += (k ? ", " : "") + loc::quoteToken(table.header[columns[k].first]) + " anchor " +
            columns[k].second;
  if (!left_out.empty()) {
    said = "WARNING: " + path + ": " + said + "; left out, naming no anchor of the anchors file: ";
    for (size_t k = 0; k < left_out.size(); ++k) said += (k ? ", " : "") + left_out[k];
  }
  s.notes.push_back(said);
  if (long_table.rows.empty()) throwInputError(path, 0, "no range in any anchor's column");
  return long_table;
}

// The ranges file's columns, from its header or its width.
struct RangeColumns {
  int t = 0, anchor = 1, range = 2, tag = -1, rx = -1, fp = -1;
  size_t width = 0;
};
RangeColumns rangeColumns(const Table& table, const std::string& path) {
  RangeColumns c;
  c.width = table.rows.front().second.size();
  if (!table.header.empty()) {
    c.t = column(table.header, kTimeNames);
    c.anchor = column(table.header, kAnchorNames);
    c.range = column(table.header, kRangeNames);
    c.tag = column(table.header, kTagNames);
    c.rx = column(table.header, {"rx_power", "rx_power_dbm"});
    c.fp = column(table.header, {"fp_power", "fp_power_dbm"});
    if (c.t < 0 || c.anchor < 0 || c.range < 0)
      throwInputError(path, 1, "the header must name the columns t, anchor_id and range");
    c.width = table.header.size();
  } else if (c.width == 4) {
    c.tag = 3;
  } else if (c.width == 5) {
    c.rx = 3, c.fp = 4;
  } else if (c.width == 6) {
    c.tag = 3, c.rx = 4, c.fp = 5;
  } else if (c.width != 3) {
    throwInputError(path, table.rows.front().first,
                    "expected 't,anchor_id,range[,tag_id][,rx_power,fp_power]', got " +
                        std::to_string(c.width) + " fields");
  }
  return c;
}

// The ranges of `table` (the file req.ranges, its columns `c`), their anchor and tag ids read by
// `anchor_ids` and `tag_ids`; without req.tags, those of `robot_tag` are the robot's.
long readRanges(const CsvImportRequest& req, const Table& table, const RangeColumns& c,
                const std::vector<uwb::Anchor>& anchors, IdNumbering& anchor_ids,
                IdNumbering& tag_ids, int robot_tag, std::vector<loc::Event>& events,
                ImportSummary& s) {
  const std::string& path = req.ranges;
  const int ct = c.t, ca = c.anchor, cr = c.range, ctag = c.tag, crx = c.rx, cfp = c.fp;
  const size_t width = c.width;
  const double t_scale = timeScale(table, static_cast<size_t>(ct), req.time_unit, path, s);
  const double r_scale =
      rangeScale(columnValues(table, static_cast<size_t>(cr)), anchors, req.range_unit, path, s);
  long n = 0;
  std::vector<double> stamps;
  for (const auto& [line, f] : table.rows) {
    if (f.size() != width)
      throwInputError(path, line,
                      "expected " + std::to_string(width) + " fields like the first row, got " +
                          std::to_string(f.size()));
    const auto t = rowTime(f[static_cast<size_t>(ct)], path, line, "range", s, t_scale);
    if (!t) continue;
    uwb::Range r;
    r.t = *t;
    r.anchor_id = anchor_ids(f[static_cast<size_t>(ca)], path, line, "anchor_id");
    r.range = parseNumber(f[static_cast<size_t>(cr)], path, line, "range") * r_scale;
    if (!std::isfinite(r.range)) {
      ++s.skipped["range_non_finite"];
      continue;
    }
    if (ctag >= 0) r.tag_id = tag_ids(f[static_cast<size_t>(ctag)], path, line, "tag_id");
    if (crx >= 0 && cfp >= 0 && !f[static_cast<size_t>(crx)].empty() &&
        !f[static_cast<size_t>(cfp)].empty()) {
      r.rx_power_dbm = parseNumber(f[static_cast<size_t>(crx)], path, line, "rx_power");
      r.fp_power_dbm = parseNumber(f[static_cast<size_t>(cfp)], path, line, "fp_power");
    }
    if (const auto it = req.tags.find(r.tag_id); it != req.tags.end()) {
      r.tag_on_robot = it->second;
      r.on_robot = true;
    } else {
      r.tag_on_robot.z() = req.tag_height.value_or(0.0);
      r.on_robot = r.tag_id == robot_tag;
    }
    events.emplace_back(r);
    stamps.push_back(r.t);
    ++n;
  }
  // Relative stamps in milliseconds read as seconds: epochs tens of seconds apart (an anchor
  // answers several times a second).
  std::sort(stamps.begin(), stamps.end());
  stamps.erase(std::unique(stamps.begin(), stamps.end()), stamps.end());
  std::vector<double> gaps;
  for (size_t i = 1; i < stamps.size(); ++i) gaps.push_back(stamps[i] - stamps[i - 1]);
  const double gap = gaps.size() >= 10 ? loc::medianOf(std::move(gaps)) : 0.0;
  if (req.time_unit == "auto" && t_scale == 1.0 && gap > 30.0) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "WARNING: %s: the ranges' epochs are a median %.4g s apart: if the times are "
                  "in milliseconds, give --time-unit ms",
                  path.c_str(), gap);
    s.notes.emplace_back(buf);
  }
  return n;
}

struct OdoRow {
  double t;
  Eigen::Vector3d v;
};

// The increments of `rows` read as `kind`, each stamped with the end of its motion.
std::vector<loc::OdometryIncrement> odometryIncrements(const std::vector<OdoRow>& rows,
                                                       const std::string& kind) {
  std::vector<loc::OdometryIncrement> out;
  for (size_t k = 0; k < rows.size(); ++k) {
    loc::OdometryIncrement o;
    o.t = rows[k].t;
    if (kind == "increments") {
      o.delta = rows[k].v;
    } else if (k == 0) {
      continue;  // poses and velocities: the first row starts the motion
    } else if (kind == "poses") {
      o.delta = relativePose(rows[k - 1].v, rows[k].v);
    } else {
      o.delta = arcIncrement(rows[k - 1].v.x(), rows[k - 1].v.y(), rows[k].t - rows[k - 1].t);
    }
    out.push_back(o);
  }
  return out;
}

// Dead reckoning of `inc` from the reference's first pose against the reference: RMS position
// error over the first 30 m travelled.
double deadReckoningError(const std::vector<loc::OdometryIncrement>& inc,
                          const std::vector<TimedPose>& ref) {
  Eigen::Vector3d pose = ref.front().pose;
  double travelled = 0.0, sum = 0.0;
  long n = 0;
  for (const auto& o : inc) {
    if (o.t <= ref.front().t) continue;
    pose = composePose(pose, o.delta);
    travelled += o.delta.head<2>().norm();
    const auto truth = interpolateGroundTruth(ref, o.t, 5.0);
    if (!truth) continue;
    sum += (truth->head<2>() - pose.head<2>()).squaredNorm();
    ++n;
    if (travelled > 30.0) break;
  }
  return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : INFINITY;
}

void readOdometry(const CsvImportRequest& req, const std::vector<TimedPose>& reference,
                  const std::vector<uwb::Anchor>& anchors, std::vector<loc::Event>& events,
                  ImportSummary& s) {
  const std::string& path = req.odometry;
  const Table table = readTable(path);
  std::string kind = req.odometry_kind;
  const size_t width =
      table.header.empty() ? table.rows.front().second.size() : table.header.size();
  if (kind == "auto" && !table.header.empty()) {
    if (column(table.header, {"dx"}) >= 0)
      kind = "increments";
    else if (column(table.header, {"v"}) >= 0)
      kind = "velocities";
    else if (column(table.header, {"x"}) >= 0)
      kind = "poses";
  }
  if (kind == "auto" && width == 3) kind = "velocities";
  const size_t need = kind == "velocities" ? 3 : 4;
  if (kind != "auto" && width != need)
    throwInputError(path, table.rows.front().first,
                    "odometry as " + kind + " has " + std::to_string(need) + " columns, got " +
                        std::to_string(width));
  if (width != 3 && width != 4)
    throwInputError(path, table.rows.front().first,
                    "expected 't,dx,dy,dtheta', 't,x,y,theta' or 't,v,omega'");
  std::vector<OdoRow> rows;
  const double t_scale = timeScale(table, 0, req.time_unit, path, s);
  for (const auto& [line, f] : table.rows) {
    if (f.size() != width)
      throwInputError(path, line, "expected " + std::to_string(width) + " fields");
    const auto t = rowTime(f[0], path, line, "odometry", s, t_scale);
    if (!t) continue;
    OdoRow r{*t, Eigen::Vector3d::Zero()};
    for (size_t i = 1; i < width; ++i)
      r.v(static_cast<long>(i - 1)) =
          parseNumber(f[i], path, line, "column " + std::to_string(i + 1));
    if (!r.v.allFinite()) {
      ++s.skipped["odometry_non_finite"];
      continue;
    }
    if (!rows.empty() && r.t <= rows.back().t) {
      ++s.skipped["odometry_time_not_increasing"];
      continue;
    }
    rows.push_back(r);
  }
  if (kind == "auto") {
    if (reference.empty())
      throwInputError(path, 0,
                      "four columns without a header: name them (t,dx,dy,dtheta or t,x,y,theta) "
                      "or give --odometry-kind increments|poses (or a --reference to decide by)");
    const double e_inc = deadReckoningError(odometryIncrements(rows, "increments"), reference);
    const double e_pose = deadReckoningError(odometryIncrements(rows, "poses"), reference);
    kind = e_pose < e_inc ? "poses" : "increments";
    char buf[240];
    std::snprintf(buf, sizeof buf,
                  "Odometry read as %s: dead reckoning follows the reference to %.2f m RMS over "
                  "the first 30 m (as %s: %.2f m)",
                  kind.c_str(), std::min(e_inc, e_pose), kind == "poses" ? "increments" : "poses",
                  std::max(e_inc, e_pose));
    s.notes.emplace_back(buf);
  }
  // Read in `c` (odometry_check.hpp): the raw columns scaled, before they become increments (a
  // pose's heading in degrees must be turned to radians before two poses are differenced).
  const auto incrementsAs = [&](const OdometryConvention& c) {
    std::vector<OdoRow> scaled = rows;
    const Eigen::Vector3d k =
        kind == "velocities" ? Eigen::Vector3d(c.scale.x(), c.scale.z(), 1.0) : c.scale;
    for (auto& r : scaled) r.v = r.v.cwiseProduct(k);
    return odometryIncrements(scaled, kind);
  };
  const auto& conventions = odometryConventions();
  std::vector<loc::OdometryIncrement> increments;
  if (req.odometry_convention == "auto") {
    std::vector<std::vector<loc::OdometryIncrement>> candidates;
    for (const auto& c : conventions) candidates.push_back(incrementsAs(c));
    size_t use = 0;  // as written
    if (const auto readings = odometryReadings(candidates, events, anchors))
      if (const auto better = betterOdometryReading(*readings)) {
        use = static_cast<size_t>(better->reading.convention - conventions.data());
        s.notes.push_back("WARNING: " + path + ": odometry read " + conventions[use].name + ": " +
                          better->describe() + " (--odometry-convention as-written keeps it)");
      }
    increments = std::move(candidates[use]);
  } else {
    const auto named = std::find_if(conventions.begin(), conventions.end(), [&](const auto& c) {
      return req.odometry_convention == c.option;
    });
    if (named == conventions.end()) {
      std::string options;
      for (const auto& c : conventions)
        options += std::string(options.empty() ? "" : ", ") + c.option;
      throw InputError("import csv: --odometry-convention must be auto or one of " + options +
                       ", got '" + req.odometry_convention + "'");
    }
    increments = incrementsAs(*named);
  }
  for (const auto& o : increments) events.emplace_back(o);
}

void readImu(const CsvImportRequest& req, std::vector<loc::Event>& events, ImportSummary& s) {
  const std::string& path = req.imu;
  const Table table = readTable(path);
  const double t_scale = timeScale(table, 0, req.time_unit, path, s);
  for (const auto& [line, f] : table.rows) {
    if (f.size() != 7) throwInputError(path, line, "expected 't,gx,gy,gz,ax,ay,az'");
    const auto t = rowTime(f[0], path, line, "imu", s, t_scale);
    if (!t) continue;
    loc::ImuSample m;
    m.t = *t;
    m.gyro_z = parseNumber(f[3], path, line, "gz");
    m.accel << parseNumber(f[4], path, line, "ax"), parseNumber(f[5], path, line, "ay");
    if (!m.accel.allFinite() || !std::isfinite(m.gyro_z)) {
      ++s.skipped["imu_non_finite"];
      continue;
    }
    events.emplace_back(m);
  }
}

// Throws, naming the line, when a reference pose is not finite or its time cannot be used.
void checkReferenceRow(const TimedPose& p, const std::string& path, int line) {
  if (!p.pose.allFinite()) throwInputError(path, line, "non-finite value");
  if (const char* problem = timestampProblem(p.t))
    throwInputError(path, line,
                    std::string("unusable time (") + problem + "; --time-unit sets the unit)");
}

// TUM, t x y theta, or t x y (no heading).
std::vector<TimedPose> readReference(const CsvImportRequest& req, ImportSummary& s, bool* heading) {
  const std::string& path = req.reference;
  const Table table = readTable(path);
  const double t_scale = timeScale(table, 0, req.time_unit, path, s);
  const size_t width = table.rows.front().second.size();
  *heading = width != 3;
  if (width == 8 || width == 4) {
    // The readers of the manifest's formats, header row apart.
    std::vector<TimedPose> out;
    std::vector<Eigen::Vector4d> quaternions;
    for (const auto& [line, f] : table.rows) {
      if (f.size() != width)
        throwInputError(path, line, "expected " + std::to_string(width) + " fields");
      TimedPose p;
      p.t = parseNumber(f[0], path, line, "t") * t_scale;
      double yaw = 0.0;
      if (width == 4) {
        yaw = parseNumber(f[3], path, line, "theta");
      } else {
        quaternions.emplace_back(
            parseNumber(f[4], path, line, "qx"), parseNumber(f[5], path, line, "qy"),
            parseNumber(f[6], path, line, "qz"), parseNumber(f[7], path, line, "qw"));
        if (!quaternions.back().allFinite()) throwInputError(path, line, "non-finite value");
      }
      p.pose << parseNumber(f[1], path, line, "x"), parseNumber(f[2], path, line, "y"), yaw;
      checkReferenceRow(p, path, line);
      if (!out.empty() && p.t < out.back().t) throwInputError(path, line, "time goes backwards");
      out.push_back(p);
    }
    // TUM: the headings of the quaternions, read scalar first when only that is planar;
    // 't,x,y,theta': read in degrees when only that follows the travel.
    std::vector<std::string> said;
    if (width == 8) {
      const auto yaw = planarHeadings(quaternions, path, &said);
      for (size_t i = 0; i < yaw.size(); ++i) out[i].pose.z() = yaw[i];
    } else {
      headingsInRadians(out, path, &said);
    }
    for (const auto& w : said) s.notes.push_back("WARNING: " + w);
    return out;
  }
  if (width != 3)
    throwInputError(path, table.rows.front().first,
                    "expected TUM (8 fields), 't,x,y,theta' or 't,x,y', got " +
                        std::to_string(width) + " fields");
  std::vector<TimedPose> out;
  for (const auto& [line, f] : table.rows) {
    if (f.size() != 3) throwInputError(path, line, "expected 't,x,y'");
    TimedPose p;
    p.t = parseNumber(f[0], path, line, "t") * t_scale;
    p.pose << parseNumber(f[1], path, line, "x"), parseNumber(f[2], path, line, "y"), 0.0;
    checkReferenceRow(p, path, line);
    if (!out.empty() && p.t < out.back().t) throwInputError(path, line, "time goes backwards");
    out.push_back(p);
  }
  return out;
}

// Each tag's place on the robot checked against the reference (fitTagOnRobot, tag_fit.hpp):
// where the ranges agree clearly better with another place (more than 0.1 m away, a median
// deviation under 0.8 times), a warning names it and the --tag that sets it. The place is not
// taken from the reference: a tag's mount is the user's to state, and an estimator configured
// from the ground truth it is scored against would flatter itself. Without a reference the
// tags' place cannot be read from the data: a note says what was assumed when nothing was given.
void checkTagPlaces(const CsvImportRequest& req, const std::vector<loc::Event>& events,
                    const std::vector<uwb::Anchor>& anchors,
                    const std::vector<TimedPose>& reference, bool heading,
                    const std::string& robot_tag, ImportSummary& s) {
  const bool given = !req.tags.empty() || req.tag_height;
  if (reference.empty()) {
    if (!given)
      s.notes.emplace_back(
          "No tag position given: tag " + robot_tag +
          " taken at the robot's origin at height 0 (--tag ID,X,Y,Z or --tag-height H sets it; a "
          "wrong height or lever arm reads as range error)");
    return;
  }
  std::map<int, std::pair<Eigen::Vector3d, std::vector<TagFitSample>>> by_tag;
  for (auto& sample : rangesBesideReference(events, anchors, reference)) {
    auto& [tag, samples] = by_tag[sample.tag_id];
    tag = sample.tag_on_robot;
    samples.push_back(std::move(sample));
  }
  for (const auto& [id, entry] : by_tag) {
    const auto& [tag, samples] = entry;
    if (samples.size() < 50) continue;
    const double at_given = loc::medianOf(rangeDeviations(samples, tag));
    const TagFit fit = fitTagOnRobot(samples, tag, heading, true);
    if ((fit.tag - tag).norm() <= 0.1 || fit.deviation >= 0.8 * at_given) continue;
    char buf[800];
    std::snprintf(buf, sizeof buf,
                  "WARNING: %s: against the reference, tag %d's ranges agree best with the tag "
                  "at (%.2f, %.2f, %.2f) m on the robot (median deviation from each anchor's "
                  "median error %.3f m), not at (%.2f, %.2f, %.2f) m %s (%.3f m%s): if that is "
                  "where it sits, give --tag %d,%.2f,%.2f,%.2f (a lag of the reference's clock "
                  "also looks like a lever arm along the travel: see the clock check below)",
                  req.ranges.c_str(), id, fit.tag.x(), fit.tag.y(), fit.tag.z(), fit.deviation,
                  tag.x(), tag.y(), tag.z(), given ? "as given" : "(none given: the origin)",
                  at_given,
                  heading ? "" : "; the reference has no heading: the lever arm is not read", id,
                  fit.tag.x(), fit.tag.y(), fit.tag.z());
    s.notes.emplace_back(buf);
  }
}

long readScans(const CsvImportRequest& req, std::vector<loc::Event>& events, ImportSummary& s) {
  const std::string& path = req.scans;
  const Table table = readTable(path);
  std::vector<loc::LaserScan> scans;
  float longest = 0.0f;
  const double t_scale = timeScale(table, 0, req.time_unit, path, s);
  for (const auto& [line, f] : table.rows) {
    if (f.size() < 4) throwInputError(path, line, "expected 't,angle_min,angle_increment,r0,...'");
    const auto t = rowTime(f[0], path, line, "scan", s, t_scale);
    if (!t) continue;
    loc::LaserScan scan;
    scan.t = *t;
    scan.sensor_pose = req.scan_pose;
    scan.sensor_height = req.scan_height;
    scan.angle_min = static_cast<float>(parseNumber(f[1], path, line, "angle_min"));
    scan.angle_increment = static_cast<float>(parseNumber(f[2], path, line, "angle_increment"));
    if (!std::isfinite(scan.angle_min) || !std::isfinite(scan.angle_increment))
      throwInputError(path, line, "angle_min and angle_increment must be finite");
    for (size_t i = 3; i < f.size(); ++i) {
      const double r =
          f[i].empty() ? NAN : parseNumber(f[i], path, line, "r" + std::to_string(i - 3));
      const bool ok = std::isfinite(r) && r > 0.0;
      scan.ranges.push_back(ok ? static_cast<float>(r) : 0.0f);
      scan.valid.push_back(ok ? 1 : 0);
      if (ok) longest = std::max(longest, static_cast<float>(r));
    }
    scans.push_back(std::move(scan));
  }
  const float max_range = req.scan_max_range ? static_cast<float>(*req.scan_max_range) : longest;
  if (!req.scan_max_range && !scans.empty()) {
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "Scan maximum range taken as the longest range in the file: %.2f m "
                  "(--scan-max-range sets it)",
                  max_range);
    s.notes.emplace_back(buf);
  }
  for (auto& scan : scans) {
    scan.max_range = max_range;
    events.emplace_back(std::move(scan));
  }
  return static_cast<long>(scans.size());
}

}  // namespace

double secondsPerTimeUnit(const std::string& unit) {
  if (unit == "s") return 1.0;
  if (unit == "ms") return 1e-3;
  if (unit == "us") return 1e-6;
  if (unit == "ns") return 1e-9;
  throw InputError("import csv: --time-unit must be auto, s, ms, us or ns, got '" + unit + "'");
}

ImportSummary importCsv(const CsvImportRequest& request, const std::string& out_dir) {
  if (request.ranges.empty()) throw InputError("import csv: --ranges is required");
  if (request.anchors.empty()) throw InputError("import csv: --anchors is required");
  CsvImportRequest req = request;
  ImportSummary s;
  std::vector<loc::Event> events;
  // Anchors written without heights ("id,x,y") are taken at the tag's: the ranges read as
  // planar distances.
  double tag_z = req.tag_height.value_or(0.0);
  if (!req.tags.empty() || !req.tag_names.empty()) {
    tag_z = 0.0;
    for (const auto& [id, at] : req.tags) tag_z += at.z();
    for (const auto& [name, at] : req.tag_names) tag_z += at.z();
    tag_z /= static_cast<double>(req.tags.size() + req.tag_names.size());
  }
  // The anchors' ids as written (a ranges file may name them in its header) and whether they
  // have heights, before the ids are numbered with the ranges'.
  std::vector<std::string> anchor_names;
  bool anchors_without_z = false;
  {
    IdNumbering scratch(1);
    for (const auto& a : loadAnchorsCsv(req.anchors, &scratch, tag_z, &anchors_without_z))
      anchor_names.push_back(scratch.nameOf(a.id));
  }
  if (anchors_without_z) {
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "WARNING: %s: the anchors have no height (id,x,y): they are taken at the tag's, "
                  "%.3g m, so the ranges are read as distances in the plane; if the anchors are "
                  "mounted higher or lower than the tag, give their z",
                  req.anchors.c_str(), tag_z);
    s.notes.emplace_back(buf);
  }
  // Anchors and tags may be named (a device's "1C8D", "A3"): every integer id the files use is
  // seen first, then the names are numbered around them (anchors from 1, tags from 0, the tags
  // named by --tag first).
  const Table range_table =
      rangesOneAnAnchorRow(readTable(req.ranges), anchor_names, req.ranges, s);
  const RangeColumns range_columns = rangeColumns(range_table, req.ranges);
  IdNumbering anchor_ids(1), tag_ids(0);
  for (const auto& [line, f] : range_table.rows) {
    if (static_cast<size_t>(range_columns.anchor) < f.size())
      anchor_ids.see(f[static_cast<size_t>(range_columns.anchor)]);
    if (range_columns.tag >= 0 && static_cast<size_t>(range_columns.tag) < f.size())
      tag_ids.see(f[static_cast<size_t>(range_columns.tag)]);
  }
  for (const auto& [id, at] : req.tags) tag_ids.see(std::to_string(id));
  for (const auto& [name, at] : req.tag_names) req.tags[tag_ids(name, "--tag", 0, "id")] = at;
  auto anchors = loadAnchorsCsv(req.anchors, &anchor_ids, tag_z);
  const auto scaleAnchors = [&](double scale) {
    for (auto& a : anchors) a.position *= scale;
  };
  if (req.anchor_unit != "auto") scaleAnchors(metresPerUnit(req.anchor_unit, "--anchor-unit"));
  std::vector<TimedPose> reference;
  bool heading = true;
  if (!req.reference.empty()) reference = readReference(req, s, &heading);
  // Without --tag, the robot's tag is tag 0, or the one tag the ranges come from.
  std::set<int> tags_ranging;
  for (const auto& [line, f] : range_table.rows)
    if (range_columns.tag >= 0 && static_cast<size_t>(range_columns.tag) < f.size())
      tags_ranging.insert(
          tag_ids(f[static_cast<size_t>(range_columns.tag)], req.ranges, line, "tag_id"));
  int robot_tag = 0;
  if (req.tags.empty() && tags_ranging.size() == 1 && *tags_ranging.begin() != 0) {
    robot_tag = *tags_ranging.begin();
    s.notes.push_back("The ranges come from tag " + tag_ids.nameOf(robot_tag) +
                      " alone: it is taken as the robot's (--tag places it)");
  } else if (req.tags.empty() && !tags_ranging.empty() && !tags_ranging.count(0)) {
    std::string list;
    for (int id : tags_ranging) list += (list.empty() ? "" : ", ") + tag_ids.nameOf(id);
    s.notes.push_back("WARNING: " + req.ranges + ": the ranges come from tags " + list +
                      ", none of them placed on the robot: every method ignores them (--tag "
                      "ID,X,Y,Z for each tag on the robot)");
  }
  s.ranges = readRanges(req, range_table, range_columns, anchors, anchor_ids, tag_ids, robot_tag,
                        events, s);
  if (s.ranges == 0) {
    std::string why;
    for (const auto& [reason, count] : s.skipped)
      if (reason.rfind("range_", 0) == 0)
        why += (why.empty() ? "" : ", ") + reason + " " + std::to_string(count);
    throwInputError(req.ranges, 0,
                    "no usable range" + (why.empty() ? std::string() : " (skipped: " + why + ")") +
                        "; --time-unit and --range-unit set the units");
  }
  if (req.anchor_unit == "auto")
    if (const auto unit = anchorUnitFromRanges(events, anchors)) {
      scaleAnchors(unit->metres);
      s.notes.push_back("WARNING: " + req.anchors + ": anchors read as " + unit->name +
                        ": in metres the ranges could not be distances to them (two ranges of "
                        "one tag, taken together, fall short of their anchors' distance apart), "
                        "in " +
                        unit->name + " they can (--anchor-unit sets the unit)");
    }
  if (!req.odometry.empty()) readOdometry(req, reference, anchors, events, s);
  if (!req.imu.empty()) readImu(req, events, s);
  if (!req.scans.empty()) s.scans = readScans(req, events, s);
  loc::sortByTime(events);
  checkTagPlaces(req, events, anchors, reference, heading, tag_ids.nameOf(robot_tag), s);
  std::set<int> unknown;
  for (const auto& e : events)
    if (const auto* r = std::get_if<uwb::Range>(&e); r && !uwb::findAnchor(anchors, r->anchor_id))
      unknown.insert(r->anchor_id);
  if (!unknown.empty()) {
    std::string ids;
    for (int id : unknown) ids += (ids.empty() ? "" : ", ") + anchor_ids.nameOf(id);
    s.notes.push_back("WARNING: ranges to anchors missing from " + req.anchors + ": " + ids +
                      " (the methods reject them as unknown_anchor)");
  }

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "csv.rawlog").string(), events);
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(anchors));
  if (!anchor_ids.named().empty() || !tag_ids.named().empty()) {
    std::string csv = "kind,name,id\n", said;
    for (const auto& [kind, ids] : {std::pair{"anchor", &anchor_ids}, {"tag", &tag_ids}}) {
      std::string list;
      for (const auto& [name, id] : ids->named()) {
        csv += std::string(kind) + "," + name + "," + std::to_string(id) + "\n";
        list += (list.empty() ? "" : ", ") + name + " = " + std::to_string(id);
      }
      if (!list.empty()) said += std::string(said.empty() ? "" : "; ") + kind + "s " + list;
    }
    writeFileAtomic((out / "ids.csv").string(), csv);
    s.notes.push_back("Named ids numbered (written to ids.csv): " + said);
  }
  ManifestDraft m;
  m.comments = {"Imported by 'uwbloc import csv' from " + fs::absolute(req.ranges).string()};
  m.name = req.name.empty() ? fs::absolute(out).filename().string() : req.name;
  m.rawlog = "csv.rawlog";
  m.anchors_csv = "anchors.csv";
  if (!req.map.empty()) {
    requireRegularFile(req.map);
    m.map = fs::absolute(req.map).string();
  }
  if (!reference.empty()) {
    writeFileAtomic((out / "ground_truth.tum").string(), formatTum(reference));
    m.ground_truth = "ground_truth.tum";
    m.ground_truth_format = GroundTruthFormat::kTum;
    m.reference_heading = heading;
    s.ground_truth_rows = static_cast<long>(reference.size());
    if (!heading) s.notes.emplace_back("The reference has no heading: heading is not scored");
  }
  bool powers = false;
  for (const auto& e : events)
    if (const auto* r = std::get_if<uwb::Range>(&e)) powers |= r->rx_power_dbm.has_value();
  if (powers) {
    writeFileAtomic((out / "range_features.csv").string(), formatRangeFeatures(events));
    m.range_features = "range_features.csv";
  }
  if (!req.tags.empty())
    m.tags = req.tags;
  else if (robot_tag != 0)
    m.tags[robot_tag] = Eigen::Vector3d(0.0, 0.0, req.tag_height.value_or(0.0));
  else if (req.tag_height)
    m.tag_height = *req.tag_height;
  s.manifest = writeManifest(out_dir, m);
  s.anchors = static_cast<long>(anchors.size());
  return s;
}

std::string exportCsv(const Dataset& ds, const std::string& out_dir) {
  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  std::string ranges = "t,anchor_id,range,tag_id,rx_power,fp_power\n", odometry, imu, scans;
  std::map<int, Eigen::Vector3d> tags;
  const loc::LaserScan* first_scan = nullptr;
  char buf[256];
  for (const auto& e : ds.events) {
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      std::snprintf(buf, sizeof buf, "%.7f,%d,%.9g,%d,", r->t, r->anchor_id, r->range, r->tag_id);
      ranges += buf;
      if (r->rx_power_dbm && r->fp_power_dbm) {
        std::snprintf(buf, sizeof buf, "%.9g,%.9g", *r->rx_power_dbm, *r->fp_power_dbm);
        ranges += buf;
      } else {
        ranges += ",";
      }
      ranges += "\n";
      if (r->on_robot) tags.try_emplace(r->tag_id, r->tag_on_robot);
    } else if (const auto* o = std::get_if<loc::OdometryIncrement>(&e)) {
      std::snprintf(buf, sizeof buf, "%.7f,%.17g,%.17g,%.17g\n", o->t, o->delta.x(), o->delta.y(),
                    o->delta.z());
      odometry += buf;
    } else if (const auto* m = std::get_if<loc::ImuSample>(&e)) {
      std::snprintf(buf, sizeof buf, "%.7f,0,0,%.17g,%.17g,%.17g,0\n", m->t, m->gyro_z,
                    m->accel.x(), m->accel.y());
      imu += buf;
    } else if (const auto* s = std::get_if<loc::LaserScan>(&e)) {
      if (!first_scan) first_scan = s;
      std::snprintf(buf, sizeof buf, "%.7f,%.9g,%.9g", s->t, s->angle_min, s->angle_increment);
      scans += buf;
      for (size_t i = 0; i < s->ranges.size(); ++i) {
        std::snprintf(buf, sizeof buf, ",%.9g", s->valid[i] ? s->ranges[i] : 0.0f);
        scans += buf;
      }
      scans += "\n";
    }
  }
  std::string args =
      "--ranges " + (out / "ranges.csv").string() + " --anchors " + (out / "anchors.csv").string();
  writeFileAtomic((out / "ranges.csv").string(), ranges);
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(ds.anchors));
  if (!odometry.empty()) {
    writeFileAtomic((out / "odometry.csv").string(), "t,dx,dy,dtheta\n" + odometry);
    args += " --odometry " + (out / "odometry.csv").string();
  }
  if (!imu.empty()) {
    writeFileAtomic((out / "imu.csv").string(), "t,gx,gy,gz,ax,ay,az\n" + imu);
    args += " --imu " + (out / "imu.csv").string();
  }
  if (!ds.ground_truth.empty()) {
    if (ds.manifest.reference_heading) {
      writeFileAtomic((out / "reference.tum").string(), formatTum(ds.ground_truth));
      args += " --reference " + (out / "reference.tum").string();
    } else {
      std::string ref;
      for (const auto& p : ds.ground_truth) {
        std::snprintf(buf, sizeof buf, "%.6f,%.6f,%.6f\n", p.t, p.pose.x(), p.pose.y());
        ref += buf;
      }
      writeFileAtomic((out / "reference.csv").string(), ref);
      args += " --reference " + (out / "reference.csv").string();
    }
  }
  if (!ds.manifest.map.empty()) args += " --map " + fs::absolute(ds.manifest.map).string();
  if (first_scan) {
    writeFileAtomic((out / "scans.csv").string(), scans);
    std::snprintf(buf, sizeof buf, " --scan-pose %.9g,%.9g,%.9g,%.9g --scan-max-range %.9g",
                  first_scan->sensor_pose.x(), first_scan->sensor_pose.y(),
                  first_scan->sensor_pose.z(), first_scan->sensor_height, first_scan->max_range);
    args += " --scans " + (out / "scans.csv").string() + buf;
  }
  for (const auto& [id, p] : tags) {
    std::snprintf(buf, sizeof buf, " --tag %d,%.9g,%.9g,%.9g", id, p.x(), p.y(), p.z());
    args += buf;
  }
  return args;
}

}  // namespace uwbloc::data
