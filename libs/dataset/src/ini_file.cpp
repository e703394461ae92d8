#include "uwbloc/dataset/ini_file.hpp"

#include <cmath>
#include <fstream>
#include <sstream>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace uwbloc::data {

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

// Strips a '#', ';' or '//' comment (MRPT config files use all three). A comment starts at the
// beginning of the line or after white space; elsewhere the marks belong to the value, so
// `front=pf-ibas:k=v;k=v` and `path=a//b` keep every character.
std::string stripComment(const std::string& s) {
  for (size_t i = 0; i < s.size(); ++i) {
    const bool mark =
        s[i] == '#' || s[i] == ';' || (s[i] == '/' && i + 1 < s.size() && s[i + 1] == '/');
    if (mark && (i == 0 || s[i - 1] == ' ' || s[i - 1] == '\t')) return s.substr(0, i);
  }
  return s;
}

}  // namespace

IniFile IniFile::load(const std::string& path) {
  requireRegularFile(path);
  std::ifstream in(path);
  if (!in) throwInputError(path, 0, "cannot open file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  return fromString(buffer.str(), path);
}

IniFile IniFile::fromString(const std::string& text, const std::string& name) {
  IniFile ini;
  ini.path_ = name;
  std::istringstream in(text);
  std::string raw, section;
  int number = 0;
  while (std::getline(in, raw)) {
    ++number;
    const std::string line = trim(stripComment(raw));
    if (line.empty()) continue;
    if (line.front() == '[') {
      if (line.back() != ']' || line.size() < 3)
        throwInputError(name, number, "malformed section header '" + line + "'");
      section = trim(line.substr(1, line.size() - 2));
      ini.data_[section];
      continue;
    }
    const auto eq = line.find('=');
    if (eq == std::string::npos || trim(line.substr(0, eq)).empty())
      throwInputError(name, number, "expected 'key = value', got '" + line + "'");
    if (section.empty()) throwInputError(name, number, "key outside of any [section]");
    const std::string key = trim(line.substr(0, eq));
    auto& entries = ini.data_[section];
    if (entries.count(key))
      throwInputError(name, number,
                      "duplicate key '" + key + "' in [" + section + "] (first on line " +
                          std::to_string(entries[key].line) + ")");
    entries[key] = {trim(line.substr(eq + 1)), number};
  }
  return ini;
}

bool IniFile::hasSection(const std::string& section) const { return data_.count(section) != 0; }

std::vector<std::string> IniFile::sections() const {
  std::vector<std::string> out;
  for (const auto& [s, e] : data_) out.push_back(s);
  return out;
}

std::vector<std::string> IniFile::keys(const std::string& section) const {
  std::vector<std::string> out;
  auto it = data_.find(section);
  if (it != data_.end())
    for (const auto& [k, e] : it->second) out.push_back(k);
  return out;
}

std::optional<std::string> IniFile::get(const std::string& section, const std::string& key) const {
  auto s = data_.find(section);
  if (s == data_.end()) return std::nullopt;
  auto k = s->second.find(key);
  if (k == s->second.end()) return std::nullopt;
  read_.insert({section, key});
  return k->second.value;
}

std::string IniFile::getString(const std::string& section, const std::string& key,
                               const std::string& fallback) const {
  return get(section, key).value_or(fallback);
}

int IniFile::lineOf(const std::string& section, const std::string& key) const {
  auto s = data_.find(section);
  if (s == data_.end()) return 0;
  auto k = s->second.find(key);
  return k == s->second.end() ? 0 : k->second.line;
}

double IniFile::getDouble(const std::string& section, const std::string& key) const {
  const auto v = get(section, key);
  if (!v) throwInputError(path_, 0, "missing key '" + key + "' in section [" + section + "]");
  const double x = parseNumber(*v, path_, lineOf(section, key), "[" + section + "] " + key);
  if (!std::isfinite(x))
    throwInputError(path_, lineOf(section, key),
                    "[" + section + "] " + key + ": expected a finite number, got " + *v);
  return x;
}

double IniFile::getDouble(const std::string& section, const std::string& key,
                          double fallback) const {
  if (!get(section, key)) return fallback;
  return getDouble(section, key);
}

void IniFile::rejectUnread() const {
  for (const auto& [section, entries] : data_)
    for (const auto& [key, entry] : entries)
      if (!read_.count({section, key}))
        throwInputError(path_, entry.line,
                        "unknown key '" + key + "' in section [" + section + "]");
}

}  // namespace uwbloc::data
