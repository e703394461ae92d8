// Small text-file helpers with errors that name the file and line.
#pragma once

#include <functional>
#include <string>
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

/// Parses an integer id (|id| < 1e9), or throws InputError naming file, line and field.
int parseId(const std::string& text, const std::string& file, int line, const std::string& field);

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
