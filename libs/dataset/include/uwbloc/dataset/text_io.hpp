// Small text-file helpers with errors that name the file and line.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace uwbloc::data {

/// Throws InputError unless `path` is a regular file (a FIFO would block a reader for ever, a
/// device would never end).
void requireRegularFile(const std::string& path);

/// Calls `on_line(line_number, fields)` for each non-empty, non-comment ('#' or '%') line, with
/// fields split on commas and/or whitespace, or on semicolons where the line has one (then a
/// field with one comma and no point reads it as the decimal mark: "1,25" is "1.25"). A UTF-8
/// byte-order mark at the start of the file is dropped. Throws InputError if the file cannot be
/// opened.
void forEachRow(const std::string& path,
                const std::function<void(int, const std::vector<std::string>&)>& on_line);

/// Parses a double, or throws InputError naming file, line and field.
double parseNumber(const std::string& text, const std::string& file, int line,
                   const std::string& field);

/// Whether all of `s` reads as a number (strtod's forms: "1e3", "0x1A", "nan" too).
bool isNumber(const std::string& s);

/// `text` as an integer id (|id| < 1e9), when it is one.
std::optional<int> integerId(const std::string& text);

/// Parses an integer id (|id| < 1e9), or throws InputError naming file, line and field.
int parseId(const std::string& text, const std::string& file, int line, const std::string& field);

/// Ids as a user's files write them: integers as they are, and names (a device's "1C8D", "A3",
/// "tag_left") numbered. A field is a name when it is no integer id (parseId) and holds a letter
/// or is no number at all ("0x6E44" reads as the integer 28228; "3.5" is an error, not a name).
/// Every integer the files use must be seen (see) before any name is numbered, so that no name
/// takes an id that an integer already has.
class IdNumbering {
 public:
  /// Names are numbered from `first` up, skipping the integers seen.
  explicit IdNumbering(int first) : next_(first) {}
  /// Keeps `text`'s integer, when it is one, from every name.
  void see(const std::string& text);
  /// `text`'s id: its integer, or its name's number (given at its first use). Throws InputError
  /// naming file, line and field for a number that is no integer id.
  int operator()(const std::string& text, const std::string& file, int line,
                 const std::string& field);
  /// The names numbered, in the order of their first use.
  const std::vector<std::pair<std::string, int>>& named() const { return named_; }
  /// The name of `id`, or its integer as text.
  std::string nameOf(int id) const;

 private:
  int next_;
  std::set<int> taken_;
  std::map<std::string, int> by_name_;
  std::vector<std::pair<std::string, int>> named_;
};

/// The latest usable timestamp [s]: about the year 3000.
inline constexpr double kLatestTimestamp = 3.3e10;

/// Why a timestamp cannot be used: "non_finite_time", "negative_time" or "absurd_time" (after the
/// year 3000, kLatestTimestamp); nullptr when it can.
/// Every reader rejects and counts such rows instead of sorting them to the start of the stream.
const char* timestampProblem(double t);

/// Creates a folder (and its parents), or throws InputError naming it.
void ensureDirectory(const std::string& path);

/// ".<pid>.<counter>.tmp": a suffix no other writer, in this process or another, uses.
std::string uniqueSuffix();

/// Writes `contents` to `path` atomically: a temporary file beside it (uniquely named), then a
/// rename.
void writeFileAtomic(const std::string& path, const std::string& contents);

}  // namespace uwbloc::data
