#include "uwbloc/evaluation/benchmark.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "uwbloc/dataset/carmen_import.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/dataset/plaza_import.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/registry.hpp"

namespace fs = std::filesystem;

namespace uwbloc::eval {

namespace {

bool wanted(const BenchmarkOptions& o, const std::string& name) {
  if (o.datasets.empty()) return true;
  for (const auto& d : o.datasets)
    if (name.find(d) != std::string::npos) return true;
  return false;
}

// Anchors for a LiDAR recording that has none: `count` reference poses spread evenly along the
// path, 2.5 m high (the same for every run, so that the table can be compared).
std::vector<uwb::Anchor> anchorsOnThePath(const std::vector<data::TimedPose>& reference,
                                          int count) {
  std::vector<uwb::Anchor> anchors;
  const size_t n = reference.size();
  for (int i = 0; i < count && n > 0; ++i) {
    const size_t k = (static_cast<size_t>(i) * n + n / 2) / static_cast<size_t>(count);
    const auto& p = reference[std::min(k, n - 1)].pose;
    anchors.push_back({i + 1, {p.x(), p.y(), 2.5}});
  }
  return anchors;
}

// The CARMEN logs: plain (LiDAR and odometry), and with simulated UWB (anchors on the path, NLOS
// where the tag-anchor segment crosses the map built from the log's own scans).
void addCarmen(const BenchmarkOptions& o, const std::string& log_name,
               std::vector<BenchmarkDataset>& out,
               const std::function<void(const std::string&)>& log) {
  const fs::path src = fs::path(o.data_dir) / "carmen_2d_laser" / (log_name + "-corrected.log.gz");
  std::error_code ec;
  if (!fs::exists(src, ec))
    return log("skipped carmen/" + log_name + ": " + src.string() + " not found");
  const fs::path dir = fs::path(o.work_dir) / "carmen" / log_name;
  if (wanted(o, "carmen/" + log_name)) {
    const auto s = data::importCarmen(src.string(), dir.string());
    out.push_back({"carmen/" + log_name, s.manifest});
  }
  if (!wanted(o, "carmen/" + log_name + "+uwb")) return;
  if (!fs::exists(dir / "reference.txt", ec)) data::importCarmen(src.string(), dir.string());
  const auto reference =
      data::readGroundTruth((dir / "reference.txt").string(), data::GroundTruthFormat::kTimeXyPhi);
  data::writeFileAtomic((dir / "anchors.csv").string(),
                        data::formatAnchorsCsv(anchorsOnThePath(reference, 6)));
  data::AugmentRequest req;
  req.rawlog = (dir / "carmen.rawlog").string();
  req.reference = (dir / "reference.txt").string();
  req.anchors_csv = (dir / "anchors.csv").string();
  req.map = "scans";
  out.push_back({"carmen/" + log_name + "+uwb",
                 data::writeAugmented(
                     req, (fs::path(o.work_dir) / "carmen" / (log_name + "_uwb")).string())});
}

bool hasEstimate(const BenchmarkCell& c) {
  return c.flag.empty() && std::isfinite(c.mean_rmse) && c.mean_rmse > 0.0;
}

std::string cellText(const BenchmarkCell& c) {
  if (c.flag == "no_estimate") return "no estimate";
  if (c.flag.rfind("error:", 0) == 0) return "error";
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.3f / %.3f", c.mean_rmse, c.worst_rmse);
  std::string s = buf;
  if (c.times_best > kTimesBestLimit) {
    std::snprintf(buf, sizeof buf, " (**%.1fx the best**)", c.times_best);
    s += buf;
  }
  if (c.coverage < 0.9) {
    if (c.coverage_max < 0.9)
      std::snprintf(buf, sizeof buf, " (cov %.2f of at most %.2f)", c.coverage, c.coverage_max);
    else
      std::snprintf(buf, sizeof buf, " (cov %.2f)", c.coverage);
    s += buf;
  }
  return s;
}

}  // namespace

std::vector<BenchmarkDataset> prepareBenchmarkDatasets(
    const BenchmarkOptions& o, const std::function<void(const std::string&)>& log) {
  std::vector<BenchmarkDataset> out;
  std::error_code ec;
  const fs::path demo = fs::path(o.project_datasets) / "mrpt_uwb_demo.ini";
  if (wanted(o, "mrpt_demo") && fs::exists(demo, ec)) out.push_back({"mrpt_demo", demo.string()});
  if (!o.data_dir.empty()) {
    for (const char* run : {"LOS_TrajA_Case1", "NLOS_TrajA_Case1", "NLOS_TrajB_Case3"}) {
      const std::string name = std::string("hanyang/") + run;
      const fs::path src = fs::path(o.data_dir) / "hanyang_outdoor_uwb" / run;
      if (!wanted(o, name)) continue;
      if (!fs::is_directory(src, ec)) {
        log("skipped " + name + ": " + src.string() + " not found");
        continue;
      }
      out.push_back(
          {name,
           data::importHanyang(src.string(), (fs::path(o.work_dir) / name).string()).manifest});
    }
    const fs::path plaza = fs::path(o.data_dir) / "plaza_cmu_range_odometry";
    if (wanted(o, "plaza/Plaza2") && fs::is_directory(plaza, ec))
      out.push_back(
          {"plaza/Plaza2",
           data::importPlaza(plaza.string(), (fs::path(o.work_dir) / "plaza").string()).manifest});
    for (const char* log_name : {"intel", "aces"}) addCarmen(o, log_name, out, log);
  } else {
    log("no data directory: the public datasets are skipped");
  }
  const fs::path scenarios = fs::path(o.project_datasets) / "scenarios";
  std::vector<fs::path> files;
  if (fs::is_directory(scenarios, ec))
    for (const auto& e : fs::directory_iterator(scenarios))
      if (e.path().extension() == ".ini") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    const std::string name = "sim/" + f.stem().string();
    if (!wanted(o, name)) continue;
    out.push_back({name, data::writeSimulation(data::loadScenario(f.string()), 1,
                                               (fs::path(o.work_dir) / name).string())});
  }
  for (const auto& d : out) log("prepared " + d.name);
  return out;
}

// A spec that names no method, or a parameter its method does not take, would fail in every
// cell: it is an error before the first run.
void checkBenchmarkMethods(const std::vector<std::string>& specs) {
  for (const auto& text : specs) {
    const auto spec = loc::MethodSpec::parse(text);
    const loc::MethodInfo* info = loc::Registry::builtin().find(spec.name);
    if (!info)
      throw loc::ParamError("unknown method '" + spec.name +
                            "' (known: " + loc::Registry::builtin().knownNames() + ")");
    loc::ParamSet params = spec.params;
    params.setContext("method '" + text + "'");
    std::vector<std::string> known;
    for (const auto& p : info->defaults) known.push_back(p.key);
    params.checkAllUsed(known);
  }
}

std::vector<BenchmarkCell> runBenchmark(const std::vector<BenchmarkDataset>& datasets,
                                        const BenchmarkOptions& o,
                                        const std::function<void(const std::string&)>& log) {
  std::vector<BenchmarkCell> cells;
  const auto methods = o.methods.empty() ? loc::Registry::builtin().names() : o.methods;
  checkBenchmarkMethods(methods);
  for (const auto& d : datasets) {
    data::Dataset ds;
    try {
      ds = data::loadDataset(d.manifest, o.data_dir);
    } catch (const std::exception& e) {
      log("skipped " + d.name + ": " + e.what());
      continue;
    }
    if (ds.collapsed_time) {
      log("skipped " + d.name + ": its timestamps have collapsed");
      continue;
    }
    // "defaults": nothing from the manifest but what the recording is; "manifest facts": also
    // the range noise measured on it, when the manifest states one.
    const double coverage_max = data::referenceReach(ds);
    std::vector<std::pair<std::string, std::optional<double>>> variants{{"defaults", std::nullopt}};
    if (ds.manifest.uwb_sigma) variants.emplace_back("manifest facts", ds.manifest.uwb_sigma);
    for (const auto& [variant, sigma] : variants) {
      ds.manifest.uwb_sigma = sigma;
      for (const auto& m : methods) {
        if (!missingNeeds(ds, m).empty()) continue;
        BenchmarkCell c;
        c.dataset = d.name;
        c.variant = variant;
        c.method = m;
        c.coverage_max = coverage_max;
        try {
          const auto s = evaluateMethod(ds, m, o.seeds, 1);
          c.mean_rmse = s.metrics.rmse_2d;
          c.worst_rmse = s.worstRmse();
          c.coverage = s.metrics.coverage;
          c.flag = resultFlag(ds, s);
        } catch (const std::exception& e) {
          c.flag = std::string("error: ") + e.what();
        }
        log(d.name + " [" + variant + "] " + m + ": " +
            (c.flag.rfind("error:", 0) == 0 ? c.flag : cellText(c)));
        cells.push_back(c);
      }
    }
  }
  rateAgainstTheBest(cells);
  return cells;
}

void rateAgainstTheBest(std::vector<BenchmarkCell>& cells) {
  std::map<std::pair<std::string, std::string>, double> best;
  for (const auto& c : cells) {
    if (!hasEstimate(c)) continue;
    const auto [it, fresh] = best.try_emplace({c.dataset, c.variant}, c.mean_rmse);
    if (!fresh) it->second = std::min(it->second, c.mean_rmse);
  }
  for (auto& c : cells)
    c.times_best = hasEstimate(c) ? c.mean_rmse / best.at({c.dataset, c.variant}) : 0.0;
}

std::string markdownTableHeader(const std::string& first, const std::vector<std::string>& columns) {
  std::string out = "| " + first + " |";
  for (const auto& c : columns) out += " " + c + " |";
  out += "\n|---|";
  for (size_t i = 0; i < columns.size(); ++i) out += "---|";
  return out + "\n";
}

std::string formatBenchmarkMarkdown(const std::vector<BenchmarkCell>& cells, int seeds) {
  std::vector<std::string> columns, rows;
  std::map<std::pair<std::string, std::string>, const BenchmarkCell*> at;
  for (const auto& c : cells) {
    const std::string col = c.variant == "defaults" ? c.dataset : c.dataset + " (manifest facts)";
    if (std::find(columns.begin(), columns.end(), col) == columns.end()) columns.push_back(col);
    if (std::find(rows.begin(), rows.end(), c.method) == rows.end()) rows.push_back(c.method);
    at[{c.method, col}] = &c;
  }
  std::ostringstream md;
  md << "2D RMSE [m], mean / worst over seeds 1-" << seeds
     << ", defaults only (a column marked \"manifest facts\" also uses the range noise the "
        "manifest states); cov = coverage when under 0.9 (\"of at most\": the most any method "
        "can cover, where the reference outlasts the recording's measurements); \"Nx the "
        "best\": the mean is more than "
     << kTimesBestLimit
     << " times the best of its column; blank: the dataset lacks the method's sensors.\n\n"
     << markdownTableHeader("method", columns);
  for (const auto& r : rows) {
    md << "| " << r << " |";
    for (const auto& c : columns) {
      const auto it = at.find({r, c});
      md << " " << (it == at.end() ? "" : cellText(*it->second)) << " |";
    }
    md << "\n";
  }
  std::vector<std::string> over;
  for (const auto& c : cells)
    if (c.times_best > kTimesBestLimit) {
      char buf[64];
      std::snprintf(buf, sizeof buf, " (%.1fx)", c.times_best);
      over.push_back(c.method + " on " + c.dataset +
                     (c.variant == "defaults" ? "" : " [" + c.variant + "]") + buf);
    }
  if (over.empty()) {
    md << "\nEvery method is within " << kTimesBestLimit << " times the best of its column.\n";
  } else {
    md << "\n"
       << over.size() << " cell(s) over " << kTimesBestLimit << " times the best of their column: ";
    for (size_t i = 0; i < over.size(); ++i) md << (i ? ", " : "") << over[i];
    md << ".\n";
  }
  return md.str();
}

std::string formatBenchmarkJson(const std::vector<BenchmarkCell>& cells, int seeds) {
  nlohmann::json j;
  j["seeds"] = seeds;
  j["cells"] = nlohmann::json::array();
  auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  for (const auto& c : cells)
    j["cells"].push_back(
        {{"dataset", c.dataset},
         {"variant", c.variant},
         {"method", c.method},
         {"rmse_2d_mean", number(c.mean_rmse)},
         {"rmse_2d_worst", number(c.worst_rmse)},
         {"coverage", number(c.coverage)},
         {"coverage_max", number(c.coverage_max)},
         {"times_best", c.times_best > 0.0 ? number(c.times_best) : nlohmann::json()},
         {"flag", c.flag.empty() ? nlohmann::json() : nlohmann::json(c.flag)}});
  return j.dump(1) + "\n";
}

}  // namespace uwbloc::eval
