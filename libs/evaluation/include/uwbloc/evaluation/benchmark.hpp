// The cross-dataset benchmark: every dataset the data directory and the project provide
// (imported or simulated into a work folder), every applicable method with its defaults only,
// several seeds; one table of mean and worst-seed 2D RMSE and coverage, as Markdown and JSON.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "uwbloc/evaluation/runner.hpp"

namespace uwbloc::eval {

struct BenchmarkOptions {
  std::string data_dir;          ///< the public datasets ("" : those parts are skipped)
  std::string project_datasets;  ///< the project's datasets/ folder (manifests, scenarios)
  std::string work_dir = "runs/benchmark";  ///< imports and simulations go here
  int seeds = 5;                            ///< seeds 1..seeds per method
  std::vector<std::string> methods;         ///< empty: every registered method
  std::vector<std::string> datasets;        ///< empty: all; else only those whose name contains one
};

/// One dataset of the benchmark, ready to load.
struct BenchmarkDataset {
  std::string name;      ///< e.g. "mrpt_demo", "hanyang/LOS_TrajA_Case1", "sim/office"
  std::string manifest;  ///< path of its manifest
};

/// Imports, augments or simulates every dataset that is available; reports each step with
/// `log` (one line each). Datasets whose source is missing are listed as skipped.
std::vector<BenchmarkDataset> prepareBenchmarkDatasets(
    const BenchmarkOptions& options, const std::function<void(const std::string&)>& log);

struct BenchmarkCell {
  std::string dataset;
  std::string variant;  ///< "defaults" or "manifest facts" (the manifest's measured [uwb] sigma)
  std::string method;
  double mean_rmse = 0.0, worst_rmse = 0.0, coverage = 0.0;
  /// The most coverage any method can reach on the dataset: under 1 where the reference outlasts
  /// the recording's measurements (data::referenceReach).
  double coverage_max = 1.0;
  std::string flag;  ///< resultFlag()
  /// The mean over the best mean of the cells of the same dataset and variant that have an
  /// estimate (rateAgainstTheBest); 0 for a cell without one.
  double times_best = 0.0;
};

/// The most times the best of its column a method's mean may be before the table flags it.
constexpr double kTimesBestLimit = 3.0;

/// Sets every cell's times_best (runBenchmark does; cells built elsewhere need it before the
/// tables flag them).
void rateAgainstTheBest(std::vector<BenchmarkCell>& cells);

/// Throws ParamError for a spec that names no method or a parameter its method does not take
/// (runBenchmark checks its own; a caller checks before preparing the datasets).
void checkBenchmarkMethods(const std::vector<std::string>& specs);

/// Runs every applicable method on every dataset, defaults only; a dataset whose manifest states
/// facts measured on it ([uwb] sigma) is also run with them.
std::vector<BenchmarkCell> runBenchmark(const std::vector<BenchmarkDataset>& datasets,
                                        const BenchmarkOptions& options,
                                        const std::function<void(const std::string&)>& log);

/// A Markdown table's header: "| first | c1 | c2 |" and its separator row, each with its newline.
std::string markdownTableHeader(const std::string& first, const std::vector<std::string>& columns);

/// Methods as rows, datasets (and variants) as columns: "mean / worst" per cell, a cell over
/// kTimesBestLimit times its column's best flagged in the cell and listed under the table.
std::string formatBenchmarkMarkdown(const std::vector<BenchmarkCell>& cells, int seeds);
std::string formatBenchmarkJson(const std::vector<BenchmarkCell>& cells, int seeds);

}  // namespace uwbloc::eval
