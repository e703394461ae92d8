// Output of a run: trajectories (TUM), metrics.json, metrics.csv, the effective configuration
// and the console table. Every file is written atomically (temporary file, then rename).
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/evaluation/trajectory_eval.hpp"

namespace uwbloc::eval {

/// Bounds of a dataset whose manifest has a [bounds] section: the square roots of the mean
/// position variance of the static CRLB (over the ground truth) and of the posterior CRLB (after
/// a 5 s burn-in). NaN when unavailable. A method's efficiency is its 2D RMSE over a bound.
struct DatasetBounds {
  double static_rmse = NAN;
  double posterior_rmse = NAN;
  std::string motion;  ///< motion model of the posterior bound
};

/// Computes the bounds when the manifest allows it (all NaN otherwise).
DatasetBounds computeBounds(const data::Dataset& dataset);

/// "t x y z qx qy qz qw" rows, z = 0; a pose without a valid heading has the identity quaternion.
std::string formatTrajectoryTum(const std::vector<loc::PoseEstimate>& trajectory);

/// metrics.json. The schema is stable: later work may add fields, never rename them.
std::string formatMetricsJson(const data::Dataset& dataset,
                              const std::vector<MethodSummary>& methods,
                              const DatasetBounds& bounds = {});
std::string formatMetricsCsv(const data::Dataset& dataset,
                             const std::vector<MethodSummary>& methods);
/// The comparison table printed on the console (and saved as report.txt).
/// `association`: how the estimates were paired with the reference (default: compare's, the
/// manifest's gt_max_gap).
std::string formatTable(const data::Dataset& dataset, const std::vector<MethodSummary>& methods,
                        const DatasetBounds& bounds = {},
                        const std::optional<Association>& association = std::nullopt);

/// The same table, from the text of a metrics.json (for runs merged by `sweep merge`); throws
/// nlohmann::json's exceptions on a malformed file.
std::string formatTableFromJson(const std::string& metrics_json);

/// The metrics.json of single-seed runs (path, text), as one compare of all their seeds would
/// have written it: the averaged figures averaged in seed order, the seeds' rows gathered, the
/// rest from the lowest seed (sweep merge). Throws data::InputError naming a malformed file.
std::string mergeMetricsJson(const std::vector<std::pair<std::string, std::string>>& files);

/// A file name for a method spec ("uwb-kf:q=0.1" -> "uwb-kf_q-0.1").
std::string fileLabel(const std::string& spec);

struct RunInfo {
  std::string dataset_manifest;
  std::string data_dir;
  uint64_t seed = 1;
  int repeat = 1;
  DatasetBounds bounds;
  double wall_seconds = NAN;  ///< of the whole compare (metrics.json: wall_time_s)
  int jobs = 1;               ///< threads it ran on
  bool plots = false;         ///< write plots/ (plots.hpp); report.html is written either way
  std::vector<std::pair<std::string, std::string>> extra_files;  ///< (name, contents)
  std::optional<Association> association;  ///< how estimates met the reference; default compare's
};

/// Holds `<out_dir>.lock` (beside the run directory) for as long as it lives, so that a second run
/// into the same directory is refused with the holder's process id. A lock whose process is gone
/// is taken over. Creating it also proves that the directory's parent is writable, before any
/// work starts. Throws data::InputError.
class RunDirectoryLock {
 public:
  explicit RunDirectoryLock(const std::string& out_dir);
  ~RunDirectoryLock();
  RunDirectoryLock(const RunDirectoryLock&) = delete;
  RunDirectoryLock& operator=(const RunDirectoryLock&) = delete;

 private:
  std::string path_;
};

/// Writes every output file of a run as a whole (metrics.json, metrics.csv, report.txt,
/// report.html, config.ini, a TUM file per method, plots/ when asked): into a temporary directory
/// beside `out_dir`, which then replaces `out_dir` (an atomic exchange when it exists). A failed or
/// interrupted run leaves the previous directory as it was; files of methods no longer run do not
/// survive.
void writeRunDirectory(const std::string& out_dir, const data::Dataset& dataset,
                       const std::vector<MethodSummary>& methods, const RunInfo& info);

/// The run's files, written into an existing folder `out_dir` (writeRunDirectory's inner part).
void writeRunFiles(const std::string& out_dir, const data::Dataset& dataset,
                   const std::vector<MethodSummary>& methods, const RunInfo& info);

}  // namespace uwbloc::eval
