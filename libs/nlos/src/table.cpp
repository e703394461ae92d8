#include "uwbloc/nlos/table.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace uwbloc::nlos {
namespace {

[[noreturn]] void fail(const std::string& path, int line, const std::string& what) {
  throw DataError(path + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + what);
}

std::vector<std::string> split(const std::string& line, char sep) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, sep)) {
    while (!field.empty() && (field.back() == '\r' || field.back() == ' ')) field.pop_back();
    while (!field.empty() && field.front() == ' ') field.erase(field.begin());
    out.push_back(field);
  }
  if (!line.empty() && line.back() == sep) out.emplace_back();
  return out;
}

// A delimited text file: header names and rows, with the separator and the decimal mark told by
// the header (';' files use decimal commas), a UTF-8 BOM dropped, and one trailing empty column
// (a header ending in the separator) tolerated.
struct Csv {
  std::string path;
  char sep = ',';
  bool decimal_comma = false;
  std::vector<std::string> header;
  std::vector<std::pair<int, std::vector<std::string>>> rows;  // (line, fields)

  int column(const std::string& name) const {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  }
  int column(std::initializer_list<const char*> names) const {
    for (const char* n : names)
      if (int c = column(n); c >= 0) return c;
    return -1;
  }
  double number(const std::pair<int, std::vector<std::string>>& row, int col,
                bool required = true) const {
    if (col < 0) return NAN;
    std::string text = row.second[static_cast<size_t>(col)];
    if (text.empty()) {
      if (required)
        fail(path, row.first, "field '" + header[static_cast<size_t>(col)] + "' is empty");
      return NAN;
    }
    if (decimal_comma) std::replace(text.begin(), text.end(), ',', '.');
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (end != text.c_str() + text.size() || !std::isfinite(v))
      fail(path, row.first,
           "field '" + header[static_cast<size_t>(col)] + "': not a number '" + text + "'");
    return v;
  }
};

Csv readCsv(const std::string& path) {
  requireRegularFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, 0, "cannot open");
  Csv csv;
  csv.path = path;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (n == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    if (csv.header.empty()) {
      const auto semis = std::count(line.begin(), line.end(), ';');
      const auto commas = std::count(line.begin(), line.end(), ',');
      csv.sep = semis > commas ? ';' : ',';
      csv.decimal_comma = csv.sep == ';';
      csv.header = split(line, csv.sep);
      if (!csv.header.empty() && csv.header.back().empty()) csv.header.pop_back();
      if (csv.header.size() < 2) fail(path, n, "header has fewer than two columns");
      continue;
    }
    auto fields = split(line, csv.sep);
    // A row may end in the separator as its header does (one empty column more).
    if (fields.size() == csv.header.size() + 1 && fields.back().empty()) fields.pop_back();
    if (fields.size() != csv.header.size())
      fail(path, n,
           "expected " + std::to_string(csv.header.size()) + " fields (as the header), got " +
               std::to_string(fields.size()));
    csv.rows.emplace_back(n, std::move(fields));
  }
  if (csv.header.empty()) fail(path, 0, "empty file");
  return csv;
}

double median(std::vector<double> v) { return medianOfFinite(v); }

int parseLabel(const Csv& csv, const std::pair<int, std::vector<std::string>>& row, int col) {
  const double v = csv.number(row, col);
  if (v != 0.0 && v != 1.0)
    fail(csv.path, row.first,
         "field '" + csv.header[static_cast<size_t>(col)] + "' must be 0 or 1");
  return static_cast<int>(v);
}

}  // namespace

void requireRegularFile(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) fail(path, 0, "cannot open: no such file");
  // A FIFO would block a reader for ever, a device would never end.
  if (!std::filesystem::is_regular_file(status)) fail(path, 0, "cannot open: not a regular file");
}

Table readGhent(const std::string& path) {
  const Csv csv = readCsv(path);
  Table t;
  t.source = path;
  const int est = csv.column("estimated_range");
  const int truth = csv.column({"distance_GT", "real_rng"});
  const int label = csv.column("label");
  if (est < 0) fail(path, 1, "missing column 'estimated_range'");
  if (truth < 0) fail(path, 1, "missing column 'distance_GT' or 'real_rng' (the true range)");
  if (label < 0) fail(path, 1, "missing column 'label'");
  // The diagnostics, each from its column when the file has it (NaN otherwise).
  const std::pair<double Sample::*, const char*> diagnostics[] = {
      {&Sample::fp_ampl1, "fp_ampl1"},         {&Sample::fp_ampl2, "fp_ampl2"},
      {&Sample::fp_ampl3, "fp_ampl3"},         {&Sample::std_noise, "std_noise"},
      {&Sample::cir_power, "CIRpower"},        {&Sample::rxpacc, "RXPACC"},
      {&Sample::fp_index, "fpindex"},          {&Sample::rx_power_dbm, "RX_power"},
      {&Sample::fp_power_dbm, "FP_power"},     {&Sample::pr, "Pr"}};
  std::vector<int> cols;
  for (const auto& d : diagnostics) cols.push_back(csv.column(d.second));
  const int c_from = csv.column("location_from"), c_to = csv.column("location_to");
  for (const auto& row : csv.rows) {
    Sample s;
    for (size_t k = 0; k < cols.size(); ++k) s.*(diagnostics[k].first) = csv.number(row, cols[k]);
    s.range = csv.number(row, est);
    s.true_range = csv.number(row, truth);
    s.label = parseLabel(csv, row, label);
    if (c_from >= 0 && c_to >= 0)
      s.group = row.second[static_cast<size_t>(c_from)] + ">" +
                row.second[static_cast<size_t>(c_to)] + "@" + row.second[static_cast<size_t>(truth)];
    t.rows.push_back(s);
  }
  if (t.rows.empty()) fail(path, 0, "no rows");

  // Units, told by the data: UWB ranges beyond 200 m do not occur, so a median range above that
  // is in millimetres; the DW1000's accumulator has at most 1016 taps, so a first-path index
  // above 1100 is the raw register value (x 64).
  std::vector<double> ranges, fpi;
  for (const auto& s : t.rows) ranges.push_back(s.range), fpi.push_back(s.fp_index);
  if (median(ranges) > 200.0) {
    for (auto& s : t.rows) s.range *= 1e-3, s.true_range *= 1e-3;
    t.notes.push_back("ranges in millimetres (median " + std::to_string(median(ranges)) +
                      "): converted to metres");
  }
  if (median(fpi) > 1100.0) {
    for (auto& s : t.rows) s.fp_index /= 64.0;
    t.notes.push_back("fpindex is the raw register value (x 64): divided by 64");
  }
  if (c_from < 0 || c_to < 0) {
    char buf[32];
    for (auto& s : t.rows) std::snprintf(buf, sizeof buf, "%.3f", s.true_range), s.group = buf;
    t.notes.push_back("no location columns: rows grouped by true range (one spot each)");
  }
  return t;
}

Table readRangeFeatures(const std::string& path) {
  const Csv csv = readCsv(path);
  Table t;
  t.source = path;
  const int c_t = csv.column("t"), c_id = csv.column("anchor_id"), c_r = csv.column("range");
  if (c_t < 0 || c_id < 0 || c_r < 0)
    fail(path, 1, "expected columns 't,anchor_id,range[,rx_power_dbm,fp_power_dbm,...]'");
  const int c_rx = csv.column("rx_power_dbm"), c_fp = csv.column("fp_power_dbm"),
            c_truth = csv.column("true_range"), c_nlos = csv.column("nlos"),
            c_inn = csv.column("innovation");
  for (const auto& row : csv.rows) {
    Sample s;
    const double time = csv.number(row, c_t);
    const double id = csv.number(row, c_id);
    s.range = csv.number(row, c_r);
    s.rx_power_dbm = csv.number(row, c_rx, false);
    s.fp_power_dbm = csv.number(row, c_fp, false);
    s.innovation = csv.number(row, c_inn, false);
    s.true_range = csv.number(row, c_truth, false);
    if (c_nlos >= 0 && !row.second[static_cast<size_t>(c_nlos)].empty())
      s.label = parseLabel(csv, row, c_nlos);
    if (s.label < 0) {
      ++t.skipped;
      continue;
    }
    char buf[48];
    std::snprintf(buf, sizeof buf, "%.0f@%.0f", id, std::floor(time / 10.0));
    s.group = buf;
    t.rows.push_back(s);
  }
  if (t.rows.empty())
    fail(path, 0,
         "no labelled rows (an 'nlos' column comes from an import with a reference, e.g. "
         "'uwbloc import hanyang')");
  return t;
}

Table readLabelledRanges(const std::string& path) {
  requireRegularFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, 0, "cannot open");
  std::string first;
  std::getline(in, first);
  if (first.find("anchor_id") != std::string::npos) return readRangeFeatures(path);
  return readGhent(path);
}

double medianOfFinite(std::vector<double>& v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return NAN;
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace uwbloc::nlos
