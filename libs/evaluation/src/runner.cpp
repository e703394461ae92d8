#include "uwbloc/evaluation/runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>

#include "uwbloc/dataset/memory_limits.hpp"
#include "uwbloc/localization/registry.hpp"
#include "uwbloc/nlos/model.hpp"

namespace uwbloc::eval {

loc::EstimatorContext makeContext(const data::Dataset& dataset, uint64_t seed) {
  loc::EstimatorContext ctx;
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
    if (p.key == "n" || p.key == "init_n" || p.key == "relocalise_n")
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

MethodSummary evaluateMethod(const data::Dataset& dataset, const std::string& spec, int repeat,
                             uint64_t seed, const loc::ParamSet& extra,
                             const ProgressFn& progress) {
  MethodSummary s;
  s.spec = spec;
  repeat = std::max(1, repeat);
  std::vector<double> rmse;
  double seconds = 0.0;
  long steps = 0;
  double sum_x = 0.0, sum_y = 0.0, sum_2d = 0.0, sum_mae = 0.0, sum_med = 0.0, sum_p95 = 0.0,
         sum_max = 0.0, sum_final = 0.0, sum_yaw = 0.0, sum_yaw_med = 0.0, sum_yaw_p95 = 0.0;
  for (int r = 0; r < repeat; ++r) {
    RunResult run = runMethod(dataset, spec, seed + static_cast<uint64_t>(r), extra, progress);
    const double gap = dataset.manifest.gt_max_gap;
    const auto errors = associate(run.trajectory, dataset.ground_truth, gap);
    const Metrics m = computeMetrics(errors, run.trajectory, dataset.ground_truth,
                                     std::max(1.0, gap / 2.0), dataset.manifest.reference_heading);
    rmse.push_back(m.rmse_2d);
    s.seed_runs.push_back({seed + static_cast<uint64_t>(r), m.rmse_2d, m.coverage, m.max_2d});
    sum_x += m.rmse_x;
    sum_y += m.rmse_y;
    sum_2d += m.rmse_2d;
    sum_mae += m.mae_2d;
    sum_med += m.median_2d;
    sum_p95 += m.p95_2d;
    sum_max += m.max_2d;
    sum_final += m.final_2d;
    sum_yaw += m.rmse_yaw_deg;
    sum_yaw_med += m.median_yaw_deg;
    sum_yaw_p95 += m.p95_yaw_deg;
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
      s.range_decisions = run.statistics.range_decisions;
      s.artifacts = run.artifacts;
    }
  }
  const double n = repeat;
  s.runs = repeat;
  s.metrics.rmse_x = sum_x / n;
  s.metrics.rmse_y = sum_y / n;
  s.metrics.rmse_2d = sum_2d / n;
  s.metrics.mae_2d = sum_mae / n;
  s.metrics.median_2d = sum_med / n;
  s.metrics.p95_2d = sum_p95 / n;
  s.metrics.max_2d = sum_max / n;
  s.metrics.final_2d = sum_final / n;
  s.metrics.rmse_yaw_deg = sum_yaw / n;
  s.metrics.median_yaw_deg = sum_yaw_med / n;
  s.metrics.p95_yaw_deg = sum_yaw_p95 / n;
  double var = 0.0;
  for (double v : rmse) var += (v - s.metrics.rmse_2d) * (v - s.metrics.rmse_2d);
  s.rmse_2d_std = repeat > 1 ? std::sqrt(var / (n - 1)) : 0.0;
  s.ms_per_step = steps > 0 ? 1e3 * seconds / static_cast<double>(steps) : 0.0;
  s.realtime_factor = seconds > 0.0 ? n * dataset.duration() / seconds : 0.0;
  return s;
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
