// `sweep merge`: the metrics.json of single-seed runs combined as one compare would have
// written them (report.hpp, mergeMetricsJson).
#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>

#include "json_numbers.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/evaluation/report.hpp"

namespace uwbloc::eval {

namespace {

using Json = nlohmann::json;

double num(const Json& j, const char* key) { return jsonNum(j, key); }
Json number(double v) { return jsonNumber(v); }

// The figures compare averages over its runs (runner.cpp, summarise); the rest are the first
// run's.
const char* const kAveraged[] = {
    "rmse_x",      "rmse_y",          "rmse_2d",        "mae_2d",          "median_2d",
    "p95_2d",      "max_2d",          "final_2d",       "rmse_yaw_deg",    "median_yaw_deg",
    "p95_yaw_deg", "rmse_2d_aligned", "rpe_trans_rmse", "rpe_rot_rmse_deg"};

// Every field the merge and the table read, with its type; a file that lacks one is named.
void checkRun(const std::string& path, const Json& doc) {
  auto need = [&path](const Json& j, const char* key, bool (Json::*is)() const, const char* what,
                      const std::string& where) {
    if (!j.is_object() || !j.contains(key) || !(j.at(key).*is)())
      throw data::InputError(path + ": not a metrics.json of uwbloc: " + where + "\"" + key +
                             "\" is missing or not " + what);
  };
  need(doc, "dataset", &Json::is_string, "a string", "");
  need(doc, "methods", &Json::is_array, "an array", "");
  for (const auto& m : doc["methods"]) {
    const std::string where = "a method's ";
    need(m, "name", &Json::is_string, "a string", where);
    need(m, "runs", &Json::is_number_integer, "an integer", where);
    need(m, "steps", &Json::is_number_integer, "an integer", where);
    for (const char* key : {"rejected", "rejected_by_anchor", "events"})
      need(m, key, &Json::is_object, "an object", where);
    need(m, "seed_runs", &Json::is_array, "an array", where);
    if (m["seed_runs"].empty() || !m["seed_runs"][0].is_object() ||
        !m["seed_runs"][0].contains("seed") || !m["seed_runs"][0]["seed"].is_number_unsigned())
      throw data::InputError(path + ": not a metrics.json of uwbloc: method " +
                             m["name"].get<std::string>() + " has no seed in seed_runs");
  }
}

}  // namespace

std::string mergeMetricsJson(const std::vector<std::pair<std::string, std::string>>& files) {
  if (files.empty()) throw data::InputError("nothing to merge");
  std::vector<Json> docs;
  for (const auto& [path, text] : files) {
    try {
      docs.push_back(Json::parse(text));
    } catch (const Json::exception& e) {
      throw data::InputError(path + ": not a metrics.json: " + e.what());
    }
    checkRun(path, docs.back());
  }
  // Every run of a method, in first-seen order of the methods; a run directory may hold several
  // methods (one compare) or one.
  std::vector<std::string> order;
  std::map<std::string, std::vector<const Json*>> runs;
  for (const auto& d : docs)
    for (const auto& m : d["methods"]) {
      const std::string name = m.at("name").get<std::string>();
      if (!runs.count(name)) order.push_back(name);
      runs[name].push_back(&m);
    }
  Json out = docs.front();
  out["methods"] = Json::array();
  out["wall_time_s"] = nullptr;
  out["jobs"] = nullptr;
  out["merged_runs"] = files.size();
  const double crlb = num(out, "crlb_rmse"), pcrb = num(out, "pcrb_rmse");
  const double duration = num(out, "duration_s");
  for (const auto& name : order) {
    // A run directory from a --repeat compare carries several seeds: each is one element of
    // seed_runs, but only the figures averaged over them; split runs carry one seed each.
    auto& group = runs[name];
    std::sort(group.begin(), group.end(), [](const Json* a, const Json* b) {
      return a->at("seed_runs").at(0).at("seed").get<uint64_t>() <
             b->at("seed_runs").at(0).at("seed").get<uint64_t>();
    });
    for (const Json* g : group)
      if (g->at("runs").get<int>() != 1)
        throw data::InputError("sweep merge: method " + name +
                               " has a run directory of several seeds (--repeat); merge runs of "
                               "one seed each, as `sweep plan` makes them");
    Json e = *group.front();
    const double n = static_cast<double>(group.size());
    for (const char* key : kAveraged) {
      double sum = 0.0;
      for (const Json* g : group) sum += num(*g, key);
      e[key] = number(sum / n);
    }
    e["runs"] = group.size();
    e["seed_runs"] = Json::array();
    double var = 0.0, seconds = 0.0, worst = 0.0;
    long steps = 0;
    const double mean = num(e, "rmse_2d");
    for (const Json* g : group) {
      e["seed_runs"].push_back(g->at("seed_runs").at(0));
      const double r = num(*g, "rmse_2d");
      var += (r - mean) * (r - mean);
      worst = std::isnan(worst) || std::isnan(r) ? NAN : std::max(worst, r);
      const long s = g->at("steps").get<long>();
      seconds += num(*g, "ms_per_step") * static_cast<double>(s) / 1e3;
      steps += s;
    }
    e["rmse_2d_std"] = group.size() > 1 ? number(std::sqrt(var / (n - 1))) : Json(0.0);
    e["rmse_2d_worst"] = number(worst);
    e["ms_per_step"] = number(steps > 0 ? 1e3 * seconds / static_cast<double>(steps) : 0.0);
    e["realtime_factor"] = number(seconds > 0.0 ? n * duration / seconds : 0.0);
    e["efficiency_crlb"] = number(num(e, "rmse_2d") / crlb);
    e["efficiency_pcrb"] = number(num(e, "rmse_2d") / pcrb);
    out["methods"].push_back(e);
  }
  return out.dump(2) + "\n";
}

}  // namespace uwbloc::eval
