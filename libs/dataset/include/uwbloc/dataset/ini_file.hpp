// A small INI reader (MRPT style: [section], key = value, '#', ';' and '//' comments) that
// remembers the line of every key, so errors can name it, and which keys were read, so unknown
// keys can be reported.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace uwbloc::data {

class IniFile {
 public:
  /// Throws InputError for a missing file or a malformed line.
  static IniFile load(const std::string& path);
  static IniFile fromString(const std::string& text, const std::string& name);

  bool hasSection(const std::string& section) const;
  std::vector<std::string> sections() const;
  std::vector<std::string> keys(const std::string& section) const;

  std::optional<std::string> get(const std::string& section, const std::string& key) const;
  std::string getString(const std::string& section, const std::string& key,
                        const std::string& fallback) const;
  /// Throws InputError (file:line) when the key is missing or not a number.
  double getDouble(const std::string& section, const std::string& key) const;
  double getDouble(const std::string& section, const std::string& key, double fallback) const;
  int lineOf(const std::string& section, const std::string& key) const;

  /// Throws InputError naming the first key (file:line) never read through get*.
  void rejectUnread() const;
  const std::string& path() const { return path_; }

 private:
  struct Entry {
    std::string value;
    int line = 0;
  };
  std::string path_;
  std::map<std::string, std::map<std::string, Entry>> data_;
  mutable std::set<std::pair<std::string, std::string>> read_;
};

}  // namespace uwbloc::data
