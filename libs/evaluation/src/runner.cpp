#include "uwbloc/evaluation/runner.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <thread>

#include "uwbloc/dataset/memory_limits.hpp"
#include "uwbloc/evaluation/trajectory_eval.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/localization/registry.hpp"
#include "uwbloc/nlos/model.hpp"

namespace uwbloc::eval {

namespace {

std::mutex learning_cache_mutex;
std::shared_ptr<loc::LearningCache> learning_cache = std::make_shared<loc::LearningCache>();

std::shared_ptr<loc::LearningCache> processLearningCache() {
  const std::lock_guard lock(learning_cache_mutex);
  return learning_cache;
}

}  // namespace

void setLearningCacheEnabled(bool enabled) {
  const std::lock_guard lock(learning_cache_mutex);
  if (!enabled)
    learning_cache.reset();
  else if (!learning_cache)
    learning_cache = std::make_shared<loc::LearningCache>();
}

loc::EstimatorContext makeContext(const data::Dataset& dataset, uint64_t seed) {
  loc::EstimatorContext ctx;
  ctx.learning_cache = processLearningCache();
  ctx.anchors = dataset.anchors;
  ctx.seed = seed;
  ctx.map = dataset.map;
  ctx.range_sigma = dataset.manifest.uwb_sigma;
  for (const auto& tag : dataset.manifest.tags) ctx.robot_tags.push_back(tag.first);
  // NLOS models named by the methods' nlos_model: read from their files once per context.
  auto cache = std::make_shared<std::map<std::string, std::shared_ptr<const nlos::Model>>>();
  ctx.nlos_models = [cache](const std::string& path) {
    auto& model = (*cache)[path];
    if (!model) model = std::make_shared<const nlos::Model>(nlos::Model::load(path));
    return model;
  };
  if (!dataset.ground_truth.empty()) {
    ctx.initial_pose = dataset.ground_truth.front().pose;
    ctx.initial_time = dataset.ground_truth.front().t;
  }
  return ctx;
}

std::string missingNeeds(const data::Dataset& dataset, const std::string& spec) {
  const auto* info = loc::Registry::builtin().find(loc::MethodSpec::parse(spec).name);
  std::string missing;
  if (!info) return missing;
  for (const auto& need : info->needs)
    if (!dataset.provides(need)) missing += (missing.empty() ? "" : ", ") + need;
  return missing;
}

MemoryEstimate estimateRunMemory(const data::Dataset& dataset, const loc::Estimator& estimator) {
  MemoryEstimate m;
  auto add = [&m](const std::string& what, double count, double unit) {
    const double bytes = count * unit;
    m.bytes += bytes;
    char text[160];
    std::snprintf(text, sizeof text, "%s%s: %.3g x %s = %s", m.parts.empty() ? "" : "; ",
                  what.c_str(), count, data::formatBytes(unit).c_str(),
                  data::formatBytes(bytes).c_str());
    m.parts += text;
  };
  add("recording events", static_cast<double>(dataset.events.size()), sizeof(loc::Event));
  double particles = 0.0;
  bool graph = false;
  for (const auto& p : estimator.parameters()) {
    if (p.key == "n" || p.key == "n_max" || p.key == "init_n" || p.key == "relocalise_n")
      particles = std::max(particles, std::strtod(p.value.c_str(), nullptr));
    graph |= p.key == "noise_rounds";
  }
  if (particles > 0) add("particles", particles, 96.0);
  const auto* info = loc::Registry::builtin().find(estimator.name());
  const bool uses_map =
      info && std::find(info->needs.begin(), info->needs.end(), "map") != info->needs.end();
  if (uses_map && dataset.map)
    add("likelihood-field cells", static_cast<double>(dataset.map->sizeX()) * dataset.map->sizeY(),
        8.0);
  if (graph) add("graph events", static_cast<double>(dataset.events.size()), 2048.0);
  return m;
}

void checkRunMemory(const data::Dataset& dataset, const loc::Estimator& estimator) {
  const MemoryEstimate m = estimateRunMemory(dataset, estimator);
  const double budget = static_cast<double>(data::memoryBudget());
  if (m.bytes <= budget) return;
  throw loc::ParamError("method '" + estimator.name() + "' would need about " +
                        data::formatBytes(m.bytes) + " (" + m.parts + "), over the limit of " +
                        data::formatBytes(budget) +
                        " (--max-memory; by default half of this machine's memory): lower the "
                        "particle count or raise --max-memory");
}

RunResult runMethod(const data::Dataset& dataset, const std::string& spec, uint64_t seed,
                    const loc::ParamSet& extra, const ProgressFn& progress) {
  const loc::EstimatorContext ctx = makeContext(dataset, seed);
  auto estimator = loc::Registry::builtin().create(spec, ctx, extra);

  RunResult result;
  result.spec = spec;
  result.name = estimator->name();
  result.parameters = estimator->parameters();
  result.seed = seed;
  result.trajectory.reserve(dataset.events.size() / 2 + 1);

  using Clock = std::chrono::steady_clock;
  const auto wall_start = Clock::now();
  auto last_report = wall_start;
  double busy = 0.0;
  auto keep = [&](std::optional<loc::PoseEstimate> est) {
    if (!est) return;
    // Several events can share a timestamp (ranges of one frame): the latest estimate wins.
    if (!result.trajectory.empty() && result.trajectory.back().t >= est->t) {
      if (result.trajectory.back().t == est->t) result.trajectory.back() = *est;
      return;
    }
    result.trajectory.push_back(*est);
  };
  const size_t n = dataset.events.size();
  for (size_t i = 0; i < n; ++i) {
    const auto t0 = Clock::now();
    auto est = estimator->process(dataset.events[i]);
    busy += std::chrono::duration<double>(Clock::now() - t0).count();
    keep(std::move(est));
    if (progress && (i & 255) == 0) {
      const auto now = Clock::now();
      if (now - wall_start > std::chrono::seconds(2) &&
          now - last_report > std::chrono::milliseconds(500)) {
        progress(static_cast<double>(i) / static_cast<double>(n),
                 std::chrono::duration<double>(now - wall_start).count(), spec);
        last_report = now;
      }
    }
  }
  const auto t0 = Clock::now();
  auto last = estimator->finishAll();
  busy += std::chrono::duration<double>(Clock::now() - t0).count();
  for (auto& e : last) keep(std::move(e));
  if (progress && Clock::now() - wall_start > std::chrono::seconds(2))
    progress(1.0, std::chrono::duration<double>(Clock::now() - wall_start).count(), spec);
  result.statistics = estimator->statistics();
  result.artifacts = estimator->artifacts();
  result.processing_seconds = busy;
  return result;
}

void parallelFor(size_t n, int jobs, const std::function<void(size_t)>& fn) {
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  std::mutex failure_mutex;
  std::exception_ptr failure;
  // Each worker takes the next index; the first failure stops the others from starting more.
  auto worker = [&]() {
    for (size_t k; !failed && (k = next.fetch_add(1)) < n;) {
      try {
        fn(k);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(failure_mutex);
        if (!failure) failure = std::current_exception();
        failed = true;
      }
    }
  };
  const int threads = std::max(1, std::min<int>(jobs, static_cast<int>(std::min<size_t>(n, 1024))));
  if (threads == 1) {
    worker();
  } else {
    std::vector<std::thread> pool;
    for (int i = 0; i < threads; ++i) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
  }
  if (failure) std::rethrow_exception(failure);
}

Metrics scoreRun(const data::Dataset& dataset, const std::vector<loc::PoseEstimate>& trajectory) {
  const double gap = dataset.manifest.gt_max_gap;
  auto pairs = associatePoses(trajectory, dataset.ground_truth, {true, gap});
  // Against a reference without heading, no heading can be judged: the RPE then compares
  // displacements in the map frame.
  if (!dataset.manifest.reference_heading)
    for (auto& p : pairs) p.heading = false;
  Metrics m = computeMetrics(errorSamples(pairs), trajectory, dataset.ground_truth,
                             std::max(1.0, gap / 2.0), dataset.manifest.reference_heading);
  if (!pairs.empty()) {
    const auto score = scoreTrajectory(pairs, Alignment::kSe2, {kRpeDeltaMetres, false});
    m.rmse_2d_aligned = score.ape_aligned.rmse;
    m.rpe_trans_rmse = score.rpe.trans.rmse;
    if (dataset.manifest.reference_heading) m.rpe_rot_rmse_deg = score.rpe.rot_deg.rmse;
  }
  return m;
}

namespace {

// A run scored; only the first seed's keeps its trajectory and per-range details.
struct ScoredRun {
  RunResult run;
  Metrics metrics;
};

ScoredRun runAndScore(const data::Dataset& dataset, const std::string& spec, uint64_t seed,
                      bool first, const loc::ParamSet& extra, const ProgressFn& progress) {
  ScoredRun s{runMethod(dataset, spec, seed, extra, progress), {}};
  s.metrics = scoreRun(dataset, s.run.trajectory);
  if (!first) {
    s.run.trajectory = {};
    s.run.statistics.range_decisions = {};
    s.run.statistics.range_rejections = {};
    s.run.artifacts = {};
  }
  return s;
}

// The runs of one method, in seed order, summarised: means over the runs, the first run's
// details. The sums run in seed order, so the figures do not depend on which thread ran what.
MethodSummary summarise(const data::Dataset& dataset, const std::string& spec,
                        std::vector<ScoredRun>& runs) {
  MethodSummary s;
  s.spec = spec;
  std::vector<double> rmse;
  double seconds = 0.0;
  long steps = 0;
  Metrics sum;
  auto zero = [](Metrics& m) {
    m.rmse_x = m.rmse_y = m.rmse_2d = m.mae_2d = m.median_2d = m.p95_2d = m.max_2d = 0.0;
    m.final_2d = m.rmse_yaw_deg = m.median_yaw_deg = m.p95_yaw_deg = 0.0;
    m.rmse_2d_aligned = m.rpe_trans_rmse = m.rpe_rot_rmse_deg = 0.0;
  };
  zero(sum);
  for (size_t r = 0; r < runs.size(); ++r) {
    const Metrics& m = runs[r].metrics;
    RunResult& run = runs[r].run;
    rmse.push_back(m.rmse_2d);
    s.seed_runs.push_back({run.seed, m.rmse_2d, m.coverage, m.max_2d});
    sum.rmse_x += m.rmse_x;
    sum.rmse_y += m.rmse_y;
    sum.rmse_2d += m.rmse_2d;
    sum.mae_2d += m.mae_2d;
    sum.median_2d += m.median_2d;
    sum.p95_2d += m.p95_2d;
    sum.max_2d += m.max_2d;
    sum.final_2d += m.final_2d;
    sum.rmse_yaw_deg += m.rmse_yaw_deg;
    sum.median_yaw_deg += m.median_yaw_deg;
    sum.p95_yaw_deg += m.p95_yaw_deg;
    sum.rmse_2d_aligned += m.rmse_2d_aligned;
    sum.rpe_trans_rmse += m.rpe_trans_rmse;
    sum.rpe_rot_rmse_deg += m.rpe_rot_rmse_deg;
    seconds += run.processing_seconds;
    steps += m.steps;
    if (r == 0) {
      s.name = run.name;
      s.metrics = m;
      s.parameters = run.parameters;
      s.trajectory = std::move(run.trajectory);
      s.rejected = run.statistics.rejected;
      s.rejected_by_anchor = run.statistics.rejected_by_anchor;
      s.accepted_ranges = run.statistics.accepted_ranges;
      s.resets = run.statistics.resets;
      s.events = run.statistics.events;
      s.estimated_noise = run.statistics.estimated_noise;
      s.estimated_range_sigma = run.statistics.estimated_range_sigma;
      s.estimated_tag_noise = run.statistics.estimated_tag_noise;
      s.estimated_range_scale = run.statistics.estimated_range_scale;
      s.estimated_range_mixture = run.statistics.estimated_range_mixture;
      s.estimated_nlos_memory = run.statistics.estimated_nlos_memory;
      s.estimated_accel_psd = run.statistics.estimated_accel_psd;
      s.estimated_motion_scale = run.statistics.estimated_motion_scale;
      s.range_decisions = std::move(run.statistics.range_decisions);
      s.range_rejections = std::move(run.statistics.range_rejections);
      s.artifacts = std::move(run.artifacts);
    }
  }
  const double n = static_cast<double>(runs.size());
  s.runs = static_cast<int>(runs.size());
  s.metrics.rmse_x = sum.rmse_x / n;
  s.metrics.rmse_y = sum.rmse_y / n;
  s.metrics.rmse_2d = sum.rmse_2d / n;
  s.metrics.mae_2d = sum.mae_2d / n;
  s.metrics.median_2d = sum.median_2d / n;
  s.metrics.p95_2d = sum.p95_2d / n;
  s.metrics.max_2d = sum.max_2d / n;
  s.metrics.final_2d = sum.final_2d / n;
  s.metrics.rmse_yaw_deg = sum.rmse_yaw_deg / n;
  s.metrics.median_yaw_deg = sum.median_yaw_deg / n;
  s.metrics.p95_yaw_deg = sum.p95_yaw_deg / n;
  s.metrics.rmse_2d_aligned = sum.rmse_2d_aligned / n;
  s.metrics.rpe_trans_rmse = sum.rpe_trans_rmse / n;
  s.metrics.rpe_rot_rmse_deg = sum.rpe_rot_rmse_deg / n;
  double var = 0.0;
  for (double v : rmse) var += (v - s.metrics.rmse_2d) * (v - s.metrics.rmse_2d);
  s.rmse_2d_std = runs.size() > 1 ? std::sqrt(var / (n - 1)) : 0.0;
  s.ms_per_step = steps > 0 ? 1e3 * seconds / static_cast<double>(steps) : 0.0;
  s.realtime_factor = seconds > 0.0 ? n * dataset.duration() / seconds : 0.0;
  return s;
}

}  // namespace

MethodSummary evaluateMethod(const data::Dataset& dataset, const std::string& spec, int repeat,
                             uint64_t seed, const loc::ParamSet& extra,
                             const ProgressFn& progress) {
  repeat = std::max(1, repeat);
  std::vector<ScoredRun> runs;
  for (int r = 0; r < repeat; ++r)
    runs.push_back(
        runAndScore(dataset, spec, seed + static_cast<uint64_t>(r), r == 0, extra, progress));
  return summarise(dataset, spec, runs);
}

namespace {

// The order in which the runs (method x seed) are taken. In order on one thread. On several,
// longest first, so that no long run starts last while the other threads idle: every method's
// first seed is taken first, in the methods' order; after that, each free thread takes a
// remaining seed of the method whose first seed took longest (a method whose first seed is
// still running counts as the longest).
class RunQueue {
 public:
  RunQueue(size_t methods, size_t per, bool longest_first)
      : per_(per), longest_first_(longest_first), first_(methods, -1.0), taken_(methods, 0) {}

  std::pair<size_t, size_t> take() {
    const std::lock_guard<std::mutex> lock(mutex_);
    size_t pick = taken_.size();
    if (!longest_first_) {
      for (pick = 0; taken_[pick] == per_;) ++pick;
    } else if (next_first_ < taken_.size()) {
      pick = next_first_++;
    } else {
      auto cost = [&](size_t m) { return first_[m] < 0.0 ? HUGE_VAL : first_[m]; };
      for (size_t m = 0; m < taken_.size(); ++m)
        if (taken_[m] < per_ && (pick == taken_.size() || cost(m) > cost(pick))) pick = m;
    }
    return {pick, taken_[pick]++};
  }

  void finished(size_t method, size_t run, std::chrono::steady_clock::duration took) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (run == 0) first_[method] = std::chrono::duration<double>(took).count();
  }

 private:
  std::mutex mutex_;
  size_t per_;
  bool longest_first_;
  std::vector<double> first_;  ///< seconds of each method's first seed; -1 until known
  std::vector<size_t> taken_;  ///< seeds taken so far, per method
  size_t next_first_ = 0;      ///< methods whose first seed has been taken
};

}  // namespace

std::vector<MethodSummary> evaluateMethods(const data::Dataset& dataset,
                                           const std::vector<MethodJob>& methods, int repeat,
                                           uint64_t seed, int jobs, const ProgressFn& progress,
                                           const RunDoneFn& run_done) {
  repeat = std::max(1, repeat);
  const size_t per = static_cast<size_t>(repeat), total = methods.size() * per;
  std::vector<std::vector<ScoredRun>> runs(methods.size(), std::vector<ScoredRun>(per));
  std::atomic<long> done{0};
  RunQueue queue(methods.size(), per, jobs > 1);
  // Each run lands in its own slot, so the summaries are the same whatever the thread count
  // and whatever the order the runs are taken in.
  parallelFor(total, jobs, [&](size_t) {
    const auto [mi, r] = queue.take();
    const auto start = std::chrono::steady_clock::now();
    runs[mi][r] = runAndScore(dataset, methods[mi].spec, seed + r, r == 0, methods[mi].extra,
                              jobs == 1 ? progress : ProgressFn());
    queue.finished(mi, r, std::chrono::steady_clock::now() - start);
    const long finished = ++done;
    if (run_done) run_done(finished, static_cast<long>(total), methods[mi].spec);
  });
  std::vector<MethodSummary> out;
  out.reserve(methods.size());
  for (size_t mi = 0; mi < methods.size(); ++mi)
    out.push_back(summarise(dataset, methods[mi].spec, runs[mi]));
  return out;
}

double MethodSummary::worstRmse() const {
  double worst = 0.0;
  for (const auto& r : seed_runs) {
    if (!std::isfinite(r.rmse_2d)) return r.rmse_2d;
    worst = std::max(worst, r.rmse_2d);
  }
  return seed_runs.empty() ? metrics.rmse_2d : worst;
}

std::string resultFlag(const data::Dataset& dataset, const MethodSummary& m) {
  if (dataset.ground_truth.empty()) return m.trajectory.empty() ? "no_estimate" : "";
  if (m.trajectory.empty() || m.metrics.associated == 0) return "no_estimate";
  if (!(m.metrics.coverage >= 0.5)) return "low_coverage";
  return "";
}

}  // namespace uwbloc::eval
