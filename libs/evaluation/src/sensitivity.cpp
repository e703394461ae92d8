#include "uwbloc/evaluation/sensitivity.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <variant>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/benchmark.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::eval {

namespace fs = std::filesystem;

std::vector<SensitivityCondition> defaultConditions(const std::vector<int>& anchor_ids) {
  std::vector<SensitivityCondition> out;
  out.push_back({"clean (sigma 0.1 m)", 0.1, {}, 0.0});
  char name[96];
  for (double b : {0.5, 1.0, 3.0}) {
    std::snprintf(name, sizeof name, "bias %.1f m on anchor %d", b, anchor_ids.front());
    out.push_back({name, 0.1, {{anchor_ids.front(), b}}, 0.0});
  }
  for (double b : {0.5, 1.0, 3.0}) {
    std::snprintf(name, sizeof name, "bias %.1f m on every anchor", b);
    SensitivityCondition c{name, 0.1, {}, 0.0};
    for (int id : anchor_ids) c.bias[id] = b;
    out.push_back(c);
  }
  for (double s : {0.05, 0.3, 0.5, 1.0}) {
    std::snprintf(name, sizeof name, "sigma %.2f m", s);
    out.push_back({name, s, {}, 0.0});
  }
  for (double span : {10.0, 30.0, 60.0}) {
    std::snprintf(name, sizeof name, "every range NLOS for %.0f s", span);
    out.push_back({name, 0.1, {}, span});
  }
  return out;
}

namespace {

/// The scenario made LOS-clean with the condition's noise and biases, simulated with data seed 1.
data::Dataset simulateCondition(data::Scenario s, const SensitivityCondition& c, bool with_bias,
                                const std::string& dir) {
  s.uwb.nlos_distribution = "constant";
  s.uwb.nlos_mean = 0.0;
  s.uwb.outlier_prob = 0.0;
  s.uwb.zero_prob = 0.0;
  s.uwb.bias = 0.0;
  s.uwb.sigma = c.sigma;
  s.uwb.sigma_per_m = 0.0;
  s.uwb.anchor_bias = with_bias ? c.bias : std::map<int, double>{};
  data::Dataset ds = data::loadDataset(data::writeSimulation(s, 1, dir), "");
  if (c.nlos_span > 0.0 && with_bias) {
    // Every range inside the span reads long by an exponential NLOS excess (mean 0.5 m).
    const double t0 = ds.start_time + (ds.end_time - ds.start_time) / 3.0;
    std::mt19937_64 rng(7);
    std::exponential_distribution<double> excess(1.0 / 0.5);
    for (auto& e : ds.events)
      if (auto* r = std::get_if<uwb::Range>(&e); r && r->t >= t0 && r->t < t0 + c.nlos_span)
        r->range += excess(rng);
  }
  return ds;
}

/// The method's spec with the true model given: sigma, no bias, nothing learnt.
std::string trueModelSpec(const std::string& method, double sigma) {
  const auto* info = loc::Registry::builtin().find(loc::MethodSpec::parse(method).name);
  std::ostringstream spec;
  spec << method << (method.find(':') == std::string::npos ? ":" : ",") << "sigma=" << sigma;
  if (info)
    for (const auto& p : info->defaults) {
      if (p.key == "bias") spec << ",bias=0";
      if (p.key == "calib") spec << ",calib=0";
    }
  return spec.str();
}

}  // namespace

std::vector<SensitivityCell> runSensitivity(const SensitivityOptions& options,
                                            const std::function<void(const std::string&)>& log) {
  data::Scenario base = data::loadScenario(options.scenario);
  base.duration = options.duration;
  std::vector<int> ids;
  for (const auto& a : base.anchors) ids.push_back(a.id);
  const auto conditions = defaultConditions(ids);
  for (const auto& name : options.conditions)
    if (std::none_of(conditions.begin(), conditions.end(),
                     [&](const SensitivityCondition& c) { return c.name == name; })) {
      std::string known;
      for (const auto& c : conditions) known += (known.empty() ? "'" : ", '") + c.name + "'";
      throw std::invalid_argument("no sensitivity condition '" + name +
                                  "'; the conditions: " + known);
    }
  std::vector<SensitivityCell> out;
  int k = 0;
  for (const auto& c : conditions) {
    // (numbered in the full list, whichever run)
    const std::string dir =
        (fs::path(options.work_dir) / ("condition_" + std::to_string(k++))).string();
    if (!options.conditions.empty() &&
        std::find(options.conditions.begin(), options.conditions.end(), c.name) ==
            options.conditions.end())
      continue;
    const data::Dataset injected = simulateCondition(base, c, true, dir + "/injected");
    const data::Dataset truth = simulateCondition(base, c, false, dir + "/true_model");
    for (const auto& m : options.methods) {
      SensitivityCell cell;
      cell.condition = c.name;
      cell.method = m;
      const auto d = evaluateMethod(injected, m, options.seeds, 1);
      cell.rmse_defaults = d.metrics.rmse_2d;
      cell.worst_defaults = d.worstRmse();
      // The true model: the ranges without the injected bias, the std given. The NLOS span has
      // no parameter to give: its reference is the run without it.
      cell.rmse_true =
          evaluateMethod(truth, trueModelSpec(m, c.sigma), options.seeds, 1).metrics.rmse_2d;
      char line[200];
      std::snprintf(line, sizeof line, "%-28s %-16s defaults %.3f (worst %.3f), true model %.3f",
                    c.name.c_str(), m.c_str(), cell.rmse_defaults, cell.worst_defaults,
                    cell.rmse_true);
      if (log) log(line);
      out.push_back(cell);
    }
  }
  return out;
}

std::string formatSensitivityMarkdown(const std::vector<SensitivityCell>& cells) {
  std::vector<std::string> methods, conditions;
  for (const auto& c : cells) {
    if (std::find(methods.begin(), methods.end(), c.method) == methods.end())
      methods.push_back(c.method);
    if (std::find(conditions.begin(), conditions.end(), c.condition) == conditions.end())
      conditions.push_back(c.condition);
  }
  std::ostringstream out;
  out << "2D RMSE [m] with defaults / with the true model given (ratio)\n\n"
      << markdownTableHeader("condition", methods);
  for (const auto& cond : conditions) {
    out << "| " << cond << " |";
    for (const auto& m : methods)
      for (const auto& c : cells)
        if (c.condition == cond && c.method == m) {
          char buf[64];
          std::snprintf(buf, sizeof buf, " %.3f / %.3f (%.2f) |", c.rmse_defaults, c.rmse_true,
                        c.ratio());
          out << buf;
        }
    out << "\n";
  }
  return out.str();
}

std::string formatSensitivityJson(const std::vector<SensitivityCell>& cells) {
  auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  nlohmann::json j = nlohmann::json::array();
  for (const auto& c : cells)
    j.push_back({{"condition", c.condition},
                 {"method", c.method},
                 {"rmse_2d_defaults", number(c.rmse_defaults)},
                 {"rmse_2d_defaults_worst", number(c.worst_defaults)},
                 {"rmse_2d_true_model", number(c.rmse_true)},
                 {"ratio", number(c.ratio())}});
  return j.dump(2) + "\n";
}

}  // namespace uwbloc::eval
