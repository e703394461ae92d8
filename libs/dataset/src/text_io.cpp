#include "uwbloc/dataset/text_io.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/localization/params.hpp"

namespace uwbloc::data {

void throwInputError(const std::string& file, int line, const std::string& message) {
  std::ostringstream out;
  out << file;
  if (line > 0) out << ":" << line;
  out << ": " << message;
  throw InputError(out.str());
}

void requireRegularFile(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throwInputError(path, 0, "file not found");
  if (!std::filesystem::is_regular_file(path, ec))
    throwInputError(path, 0, "not a regular file (a directory, FIFO or device is not read)");
}

void forEachRow(const std::string& path,
                const std::function<void(int, const std::vector<std::string>&)>& on_line) {
  requireRegularFile(path);
  std::ifstream in(path);
  if (!in) throwInputError(path, 0, "cannot open file");
  std::string line;
  int number = 0;
  std::vector<std::string> fields;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // A spreadsheet's "CSV UTF-8" starts with a byte-order mark, which would stick to the first
    // header name.
    if (number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#' || line[first] == '%') continue;
    fields.clear();
    // Semicolon-separated (a spreadsheet's export where the comma is the decimal mark), else
    // comma-separated.
    const char separator = line.find(';') != std::string::npos ? ';' : ',';
    if (line.find(separator) != std::string::npos) {
      // Keep empty fields, trim blanks around each.
      std::string field;
      std::istringstream cells(line);
      while (std::getline(cells, field, separator)) {
        const auto b = field.find_first_not_of(" \t");
        const auto e = field.find_last_not_of(" \t");
        fields.push_back(b == std::string::npos ? "" : field.substr(b, e - b + 1));
        // One decimal comma and no point: "1,25" is 1.25.
        std::string& f = fields.back();
        if (separator == ';' && std::count(f.begin(), f.end(), ',') == 1 &&
            f.find('.') == std::string::npos)
          f[f.find(',')] = '.';
      }
      if (line.back() == separator) fields.emplace_back();
    } else {
      std::istringstream cells(line);
      std::string field;
      while (cells >> field) fields.push_back(field);
    }
    on_line(number, fields);
  }
}

double parseNumber(const std::string& text, const std::string& file, int line,
                   const std::string& field) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE)
    throwInputError(file, line,
                    "field '" + field + "': expected a number, got " + loc::quoteToken(text));
  return v;
}

int parseId(const std::string& text, const std::string& file, int line, const std::string& field) {
  const double v = parseNumber(text, file, line, field);
  if (!(std::abs(v) < 1e9) || v != std::floor(v))
    throwInputError(
        file, line,
        "field '" + field + "': expected an integer id (|id| < 1e9), got " + loc::quoteToken(text));
  return static_cast<int>(v);
}

bool isNumber(const std::string& s) {
  if (s.empty()) return false;
  char* end = nullptr;
  std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size();
}

std::optional<int> integerId(const std::string& text) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE ||
      !(std::abs(v) < 1e9) || v != std::floor(v))
    return std::nullopt;
  return static_cast<int>(v);
}

void IdNumbering::see(const std::string& text) {
  if (const auto id = integerId(text)) taken_.insert(*id);
}

int IdNumbering::operator()(const std::string& text, const std::string& file, int line,
                            const std::string& field) {
  if (const auto id = integerId(text)) return *id;
  const bool letter = std::any_of(text.begin(), text.end(), [](char c) {
    return std::isalpha(static_cast<unsigned char>(c)) != 0;
  });
  if (text.empty() || (isNumber(text) && !letter))
    return parseId(text, file, line, field);  // throws
  if (const auto it = by_name_.find(text); it != by_name_.end()) return it->second;
  while (taken_.count(next_)) ++next_;
  taken_.insert(next_);
  by_name_.emplace(text, next_);
  named_.emplace_back(text, next_);
  return next_++;
}

std::string IdNumbering::nameOf(int id) const {
  for (const auto& [name, n] : named_)
    if (n == id) return name;
  return std::to_string(id);
}

const char* timestampProblem(double t) {
  if (!std::isfinite(t)) return "non_finite_time";
  if (t < 0.0) return "negative_time";
  // Beyond the year 3000 (a negative stamp stored as an unsigned MRPT timestamp reads back as
  // about 1.8e12 s).
  if (t > kLatestTimestamp) return "absurd_time";
  return nullptr;
}

void ensureDirectory(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) throwInputError(path, 0, "cannot create folder: " + ec.message());
}

std::string uniqueSuffix() {
  static std::atomic<unsigned long> counter{0};
  return "." + std::to_string(::getpid()) + "." + std::to_string(counter++) + ".tmp";
}

void writeFileAtomic(const std::string& path, const std::string& contents) {
  const std::string tmp = path + uniqueSuffix();
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throwInputError(path, 0, "cannot write file");
    out << contents;
    out.flush();
    if (!out) throwInputError(path, 0, "write failed");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throwInputError(path, 0, "cannot rename temporary file: " + ec.message());
}

}  // namespace uwbloc::data
