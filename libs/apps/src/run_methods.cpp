// `uwbloc run` and `uwbloc compare`.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdio>
#include <functional>
#include <future>
#include <iostream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "commands.hpp"
#include "uwbloc/dataset/data_dir.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ini_file.hpp"
#include "uwbloc/dataset/memory_limits.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::apps {

namespace {

// The method list, or every registered method for 'all'.
std::vector<std::string> splitMethods(const std::string& list) {
  auto out = splitMethodSpecs(list);
  if (out.size() == 1 && out[0] == "all") return loc::Registry::builtin().names();
  return out;
}

// Parameters from --config ([method] sections) and --set method.key=value, read once and keyed
// by method. Both name methods by their registry name: a name that is no method is a typo that
// would otherwise be ignored without a word, so it is an error.
std::map<std::string, loc::ParamSet> methodOverrides(const RunOptions& opt) {
  const auto& registry = loc::Registry::builtin();
  std::map<std::string, loc::ParamSet> out;
  if (!opt.config.empty()) {
    const auto ini = data::IniFile::load(opt.config);
    for (const auto& section : ini.sections()) {
      if (!registry.find(section))
        throw loc::ParamError(opt.config + ": section [" + section +
                              "] is not a method (known: " + registry.knownNames() + ")");
      for (const auto& key : ini.keys(section)) out[section].set(key, *ini.get(section, key));
    }
  }
  for (const auto& s : opt.sets) {
    const auto o = loc::SetOverride::parse(s, registry);
    out[o.method].set(o.key, o.value);
  }
  return out;
}

// The overrides of the method a spec names (empty when none).
loc::ParamSet overridesFor(const std::map<std::string, loc::ParamSet>& overrides,
                           const std::string& spec) {
  const auto it = overrides.find(loc::MethodSpec::parse(spec).name);
  return it == overrides.end() ? loc::ParamSet{} : it->second;
}

// A bar with the rate and the time left, on a terminal only: redirected output stays clean.
void printProgress(double fraction, double elapsed_s, const std::string& label) {
  if (!isatty(fileno(stderr))) return;
  const int width = 30, done = static_cast<int>(fraction * width + 0.5);
  const double left = fraction > 0.0 ? elapsed_s * (1.0 - fraction) / fraction : 0.0;
  std::fprintf(stderr, "\r%-24.24s [%s%s] %3.0f%%  %.0f s, %.0f s left  ", label.c_str(),
               std::string(static_cast<size_t>(done), '#').c_str(),
               std::string(static_cast<size_t>(width - done), '.').c_str(), 100.0 * fraction,
               elapsed_s, left);
  if (fraction >= 1.0) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

// Checks every method spec before spending time on any run. With 'all', methods whose needs
// (ranges, scans, odometry, map) the dataset lacks are skipped; named ones are errors.
// With `jobs` runs at once, the `jobs` largest may run together: when their estimated memory
// exceeds the budget, fewer threads are used (said on stderr). Returns the thread count.
int jobsWithinMemory(const std::vector<double>& bytes, int jobs) {
  std::vector<double> largest = bytes;
  std::sort(largest.begin(), largest.end(), std::greater<>());
  const double budget = static_cast<double>(data::memoryBudget());
  const int wanted = std::min<int>(jobs, static_cast<int>(largest.size()));
  double sum = 0.0;
  int fit = 0;
  while (fit < wanted && sum + largest[static_cast<size_t>(fit)] <= budget)
    sum += largest[static_cast<size_t>(fit++)];
  if (fit >= wanted) return jobs;
  fit = std::max(1, fit);
  std::fprintf(stderr,
               "Running %d at a time instead of %d: the largest runs together would need more "
               "than the memory limit of %s (--max-memory)\n",
               fit, jobs, data::formatBytes(budget).c_str());
  return fit;
}

std::vector<std::string> runnableMethods(const data::Dataset& ds, const RunOptions& opt,
                                         const std::map<std::string, loc::ParamSet>& overrides,
                                         const std::vector<std::string>& methods, bool all,
                                         int& jobs) {
  std::vector<std::string> runnable;
  for (const auto& m : methods) {
    const std::string missing = eval::missingNeeds(ds, m);
    if (missing.empty()) {
      runnable.push_back(m);
      continue;
    }
    if (!all)
      throw loc::ParamError("method '" + m + "' needs what dataset '" + ds.name +
                            "' lacks: " + missing);
    std::fprintf(stderr, "Skipping %s: the dataset has no %s\n", m.c_str(), missing.c_str());
  }
  // Building each method once checks its parameters and its memory; a map's likelihood field
  // makes that take a while, so the methods are built on every thread.
  std::vector<double> bytes(runnable.size(), 0.0);
  eval::parallelFor(runnable.size(), jobs, [&](size_t i) {
    const auto estimator = loc::Registry::builtin().create(
        runnable[i], eval::makeContext(ds, opt.seed), overridesFor(overrides, runnable[i]));
    eval::checkRunMemory(ds, *estimator);
    bytes[i] = eval::estimateRunMemory(ds, *estimator).bytes;
  });
  jobs = jobsWithinMemory(bytes, jobs);
  return runnable;
}

}  // namespace

void RunMethodsCommand::declare(CLI::App& parser) {
  subcommand_ =
      compare_ ? parser.add_subcommand(
                     "compare", "Run several methods on one dataset and print the comparison table")
               : parser.add_subcommand("run", "Run one method on a dataset and score it");
  auto* cmd = subcommand_;
  RunOptions& opt = options_;
  cmd->add_option("--dataset,-d", opt.dataset,
                  "dataset manifest (INI); looked up as given, then in the data directory, then "
                  "in the project's datasets/")
      ->capture_default_str();
  cmd->add_option("--data-dir", opt.data_dir,
                  "folder of public datasets (default: $UWBLOC_DATA_DIR, else ../shared/datasets)");
  cmd->add_option("--out,-o", opt.out, "run directory to write (default: runs/<dataset>)");
  cmd->add_option("--seed", opt.seed, "random seed of the first run")->capture_default_str();
  cmd->add_option("--config", opt.config,
                  "INI file with one [method-name] section of parameters per method");
  cmd->add_option("--set", opt.sets, "override one parameter: method.key=value (repeatable)");
  cmd->add_flag("--allow-partial-reference", opt.allow_partial_reference,
                "score against a reference that covers under half of the recording (a loud "
                "warning instead of an error)");
  cmd->add_flag("--strict", opt.strict,
                "exit with code 3 when a method produced no estimate or covers under half of the "
                "ground truth");
  cmd->add_flag("--allow-bad-time", opt.allow_bad_time,
                "score a recording whose timestamps have collapsed (far fewer distinct stamps "
                "than messages) instead of refusing it");
  cmd->add_option("--max-memory", opt.max_memory,
                  "refuse a run whose estimated memory (recording, particles, map, graph) exceeds "
                  "this, e.g. 512M or 4G; it also bounds what a corrupt rawlog may make the "
                  "reader allocate (default: half of this machine's memory)")
      ->check([](const std::string& text) {
        return data::parseByteSize(text) ? std::string()
                                         : "expected a size such as 512M or 4G, got " + text;
      });
  plots_ = compare_;
  cmd->add_flag("--plots,!--no-plots", plots_,
                std::string("write plots/ (PNG pictures of the trajectories, errors, range "
                            "residuals and swarm spread) into the run directory (default: ") +
                    (compare_ ? "on" : "off") + "); report.html is written either way");
  if (compare_) {
    methods_ = "all";
    cmd->add_option("--methods,-m", methods_,
                    "comma-separated method specs, or 'all' for every registered method")
        ->capture_default_str();
    cmd->add_option("--repeat", opt.repeat, "runs per method (seeds seed, seed+1, ...)")
        ->capture_default_str()
        ->check(CLI::Range(1, 1000));
    jobs_ = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    cmd->add_option("--jobs,-j", jobs_,
                    "runs (method x seed) at once, one thread each; the results are those of "
                    "--jobs 1, bit for bit, apart from the timing fields and the event "
                    "range_model_reused (default: the core "
                    "count). Each run holds its own copy of the estimator's memory.")
        ->capture_default_str()
        ->check(CLI::Range(1, 256));
    cmd->add_flag("--own-learning", own_learning_,
                  "every method solves its own learning start (the range model and q it learns "
                  "from the first calib seconds with graph-uwb). By default methods whose start "
                  "would be the same share one solve, and their ms/step may leave it out "
                  "(event: range_model_reused)");
  } else {
    methods_ = "uwb-ekf";
    cmd->add_option("--method,-m", methods_,
                    "method spec, e.g. uwb-kf:q=0.1 (see 'uwbloc methods')")
        ->capture_default_str();
  }
}

int RunMethodsCommand::run() {
  const RunOptions& opt = options_;
  if (!opt.max_memory.empty()) data::setMemoryBudget(*data::parseByteSize(opt.max_memory));
  const auto overrides = methodOverrides(opt);
  const std::string data_dir = data::resolveDataDir(opt.data_dir);
  const std::string manifest = data::resolveInputPath(opt.dataset, data_dir);
  std::fprintf(stderr, "Loading %s\n", manifest.c_str());
  data::Dataset ds = data::loadDataset(manifest, data_dir);
  if (const auto w = data::referenceCoverageWarning(ds)) {
    if (!opt.allow_partial_reference)
      throw data::InputError(*w + " (--allow-partial-reference scores it anyway)");
    ds.warnings.push_back(*w);
  }
  for (const auto& w : ds.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  if (ds.collapsed_time && !opt.allow_bad_time)
    throw data::InputError(ds.manifest.rawlog +
                           ": refusing to score a recording whose timestamps have collapsed "
                           "(--allow-bad-time scores it anyway)");
  // The run directory: --out, or runs/<dataset name> with the name reduced to a safe file name
  // (a manifest's name cannot point the output elsewhere). Locked before any work starts.
  const std::string out = opt.out.empty() ? "runs/" + safeName(ds.name) : opt.out;
  const eval::RunDirectoryLock lock(out);
  const bool all = compare_ && methods_ == "all";
  const auto methods = compare_ ? splitMethods(methods_) : std::vector<std::string>{methods_};
  std::vector<eval::MethodJob> jobs;
  const auto wall_start = std::chrono::steady_clock::now();
  int jobs_used = jobs_;
  eval::setLearningCacheEnabled(!own_learning_);
  for (const auto& m : runnableMethods(ds, opt, overrides, methods, all, jobs_used))
    jobs.push_back({m, overridesFor(overrides, m)});
  // The bounds (a CRLB over the reference) need no run: computed beside them.
  auto bounds_future = std::async(std::launch::async, [&ds] { return eval::computeBounds(ds); });
  // One thread: a progress bar per run. Several: a line per finished run, on a terminal only.
  const eval::RunDoneFn run_done = [](long done, long total, const std::string& spec) {
    if (!isatty(fileno(stderr))) return;
    static std::mutex mutex;
    const std::lock_guard<std::mutex> lock(mutex);
    std::fprintf(stderr, "\r[%ld/%ld runs] %-40.40s", done, total, spec.c_str());
    if (done == total) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  };
  std::vector<eval::MethodSummary> summaries =
      eval::evaluateMethods(ds, jobs, opt.repeat, opt.seed, jobs_used, printProgress,
                            jobs_used > 1 ? run_done : eval::RunDoneFn());
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const eval::DatasetBounds bounds = bounds_future.get();
  eval::writeRunDirectory(
      out, ds, summaries,
      {manifest, data_dir, opt.seed, opt.repeat, bounds, wall_s, jobs_used, plots_, {}, {}});
  std::cout << eval::formatTable(ds, summaries, bounds);
  std::printf(
      "Wall time of the %zu runs (with building and checking every method): %.2f s on %d "
      "thread(s)\n",
      jobs.size() * static_cast<size_t>(opt.repeat), wall_s,
      std::min<int>(jobs_used, static_cast<int>(jobs.size()) * opt.repeat));
  std::cout << "Run directory: " << out << "\n";
  // No valid result at all is never a success; with --strict, neither is any flagged method.
  long flagged = 0, without_estimate = 0;
  for (const auto& m : summaries) {
    const std::string flag = eval::resultFlag(ds, m);
    flagged += !flag.empty();
    without_estimate += flag == "no_estimate";
  }
  if (summaries.empty() || without_estimate == static_cast<long>(summaries.size()))
    return kNoResult;
  return opt.strict && flagged > 0 ? kNoResult : kSuccess;
}

}  // namespace uwbloc::apps
