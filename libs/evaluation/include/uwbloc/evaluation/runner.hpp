// Runs methods over a dataset and scores them: the harness behind `uwbloc run` and `compare`.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/params.hpp"

namespace uwbloc::eval {

/// Called now and then on long runs: fraction done in [0, 1] and the method's label.
/// Progress of a long run: the fraction done, the seconds it has taken so far, and the label.
using ProgressFn = std::function<void(double fraction, double elapsed_s, const std::string& label)>;

struct RunResult {
  std::string spec;                           ///< method spec as given
  std::string name;                           ///< registry name
  std::vector<loc::ParamInfo> parameters;     ///< effective parameters
  std::vector<loc::PoseEstimate> trajectory;  ///< one pose per timestamp (the latest wins)
  loc::EstimatorStatistics statistics;
  double processing_seconds = 0.0;                             ///< wall time inside the estimator
  std::vector<std::pair<std::string, std::string>> artifacts;  ///< extra files of the method
  uint64_t seed = 0;
};

/// What a method is given: anchors, map, the first ground-truth pose as start pose, the seed,
/// and this process's learning cache while it is on.
loc::EstimatorContext makeContext(const data::Dataset& dataset, uint64_t seed);

/// The runs of this process (a compare, a benchmark, a test binary) share one learning cache
/// (loc::LearningCache): methods with identical learning starts solve them once. Off (compare
/// --own-learning): every run solves its own start, and its time includes it. On by default;
/// turning it off empties it.
void setLearningCacheEnabled(bool enabled);

/// The dataset lacks something the method needs: returns what (empty when nothing is missing).
std::string missingNeeds(const data::Dataset& dataset, const std::string& spec);

/// What a run is expected to allocate, and the parts it adds up ("particles: 1e+06 x 96 B =
/// 92 MiB; ..."). The per-unit sizes were measured (README, "Limits"): 96 B a particle, 8 B a
/// map cell of the likelihood field, 2 KiB an event for the graph smoothers, the recording at
/// the size of its events.
struct MemoryEstimate {
  double bytes = 0.0;
  std::string parts;
};
MemoryEstimate estimateRunMemory(const data::Dataset& dataset, const loc::Estimator& estimator);

/// Throws loc::ParamError, naming the method, the estimate's parts and the limit, when the
/// estimate exceeds the memory budget (data::memoryBudget(), set by --max-memory).
void checkRunMemory(const data::Dataset& dataset, const loc::Estimator& estimator);

/// Replays the dataset through one method. The start pose and time given to the method are the
/// first ground-truth pose, when there is one.
RunResult runMethod(const data::Dataset& dataset, const std::string& spec, uint64_t seed,
                    const loc::ParamSet& extra = {}, const ProgressFn& progress = nullptr);

/// One seed's figures of a repeated run.
struct SeedRun {
  uint64_t seed = 0;
  double rmse_2d = 0.0, coverage = 0.0, max_2d = 0.0;
};

struct MethodSummary {
  std::string spec;
  std::string name;
  int runs = 0;
  Metrics metrics;           ///< of the first run (trajectory, CDF), with rmse averaged over runs
  double rmse_2d_std = 0.0;  ///< std of the 2D RMSE over runs
  std::vector<SeedRun> seed_runs;  ///< every run's figures, in seed order
  /// The worst seed's 2D RMSE (NaN when a seed scored nothing).
  double worstRmse() const;
  double ms_per_step = 0.0;
  double realtime_factor = 0.0;  ///< dataset duration / processing time
  std::map<std::string, long> rejected;
  std::map<int, std::map<std::string, long>> rejected_by_anchor;
  long accepted_ranges = 0;
  long resets = 0;
  std::map<std::string, long> events;                 ///< non-rejection events by name (first run)
  std::map<int, loc::NoiseEstimate> estimated_noise;  ///< per anchor id (first run)
  std::optional<double> estimated_range_sigma;        ///< the model's range std (first run)
  std::map<int, loc::NoiseEstimate> estimated_tag_noise;  ///< per tag id (first run)
  std::optional<double> estimated_range_scale;        ///< the model's range scale (first run)
  std::optional<loc::RangeMixture> estimated_range_mixture;  ///< the range likelihood in force
  std::optional<double> estimated_nlos_memory;  ///< its links' NLOS state time constant [s]
  std::optional<double> estimated_accel_psd;  ///< the learnt motion q [m^2/s^3] (first run)
  std::optional<double> estimated_motion_scale;  ///< the learnt odometry noise scale (first run)
  std::vector<loc::ParamInfo> parameters;
  std::vector<loc::PoseEstimate> trajectory;        ///< of the first run
  std::vector<loc::RangeDecision> range_decisions;  ///< of the first run (NLOS-judging methods)
  std::vector<loc::RangeRejection> range_rejections;  ///< of the first run (its front end)
  std::vector<std::pair<std::string, std::string>> artifacts;  ///< of the first run
};

/// Why a method's result cannot stand as a result: "no_estimate" (nothing produced, or nothing
/// that overlaps the ground truth) or "low_coverage" (under half of the ground-truth samples
/// have an estimate within 1 s); empty when it is fine or there is no ground truth to judge by.
std::string resultFlag(const data::Dataset& dataset, const MethodSummary& m);

/// Metrics of one run's trajectory against the dataset's ground truth, with the aligned RMSE
/// and the RPE (trajectory_eval.hpp) filled in.
Metrics scoreRun(const data::Dataset& dataset, const std::vector<loc::PoseEstimate>& trajectory);

/// Runs `spec` `repeat` times with seeds seed, seed+1, ... and summarises.
MethodSummary evaluateMethod(const data::Dataset& dataset, const std::string& spec, int repeat,
                             uint64_t seed, const loc::ParamSet& extra = {},
                             const ProgressFn& progress = nullptr);

/// Calls fn(0) ... fn(n - 1) on up to `jobs` threads (each index once, in no set order). After
/// a failure no new index starts; the first exception is rethrown once the running ones end.
void parallelFor(size_t n, int jobs, const std::function<void(size_t)>& fn);

/// One method of a compare, with its parameter overrides.
struct MethodJob {
  std::string spec;
  loc::ParamSet extra;
};

/// Called as each run ends: runs finished, runs in all, the method's spec (from any thread).
using RunDoneFn = std::function<void(long done, long total, const std::string& spec)>;

/// Every method, `repeat` seeds each, on up to `jobs` threads (one run each). The summaries are
/// those of evaluateMethod, method by method, bit for bit, whatever `jobs` is (apart from the
/// timing fields). `progress` is only called when jobs == 1; `run_done` after every run.
/// An exception in any run is rethrown after the running ones end.
std::vector<MethodSummary> evaluateMethods(const data::Dataset& dataset,
                                           const std::vector<MethodJob>& methods, int repeat,
                                           uint64_t seed, int jobs,
                                           const ProgressFn& progress = nullptr,
                                           const RunDoneFn& run_done = nullptr);

}  // namespace uwbloc::eval
