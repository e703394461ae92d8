// uwbloc: replay recorded UWB / LiDAR / odometry data through localisation methods and score
// them against ground truth. Thin: it parses arguments and calls the libraries.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "uwbloc/dataset/carmen_import.hpp"
#include "uwbloc/dataset/data_dir.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/dataset/ini_file.hpp"
#include "uwbloc/dataset/plaza_import.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/optimizer_table.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

namespace {

using namespace uwbloc;

// "a:k=v,k=v,b" -> {"a:k=v,k=v", "b"}: an item with '=' but no ':' continues the previous spec.
std::vector<std::string> splitMethods(const std::string& list) {
  std::vector<std::string> out;
  std::string item;
  std::istringstream in(list);
  while (std::getline(in, item, ',')) {
    if (item.empty()) continue;
    if (item.find('=') != std::string::npos && item.find(':') == std::string::npos && !out.empty())
      out.back() += "," + item;
    else
      out.push_back(item);
  }
  if (out.size() == 1 && out[0] == "all") return loc::Registry::builtin().names();
  return out;
}

// Parameters for one method from --config (its [method] section) and --set method.key=value.
loc::ParamSet extraParams(const std::string& method_name, const std::string& config_path,
                          const std::vector<std::string>& sets) {
  loc::ParamSet extra;
  if (!config_path.empty()) {
    const auto ini = data::IniFile::load(config_path);
    for (const auto& key : ini.keys(method_name)) extra.set(key, *ini.get(method_name, key));
  }
  for (const auto& s : sets) {
    const auto eq = s.find('=');
    const auto dot = s.rfind('.', eq);
    if (eq == std::string::npos || dot == std::string::npos)
      throw loc::ParamError("--set expects method.key=value, got '" + s + "'");
    if (s.substr(0, dot) == method_name)
      extra.set(s.substr(dot + 1, eq - dot - 1), s.substr(eq + 1));
  }
  return extra;
}

void printProgress(double fraction, const std::string& label) {
  const bool tty = isatty(fileno(stderr));
  std::fprintf(stderr, "%s[%s] %3.0f%%%s", tty ? "\r" : "", label.c_str(), 100.0 * fraction,
               tty ? (fraction >= 1.0 ? "\n" : "") : "\n");
  std::fflush(stderr);
}

struct CommonOptions {
  std::string dataset = "mrpt_uwb_demo.ini";
  std::string data_dir;
  std::string out;
  std::string config;
  std::vector<std::string> sets;
  uint64_t seed = 1;
  int repeat = 1;
};

int runMethods(const CommonOptions& opt, const std::vector<std::string>& methods,
               bool all_methods = false) {
  const std::string data_dir = data::resolveDataDir(opt.data_dir);
  const std::string manifest = data::resolveInputPath(opt.dataset, data_dir);
  std::fprintf(stderr, "Loading %s\n", manifest.c_str());
  const data::Dataset ds = data::loadDataset(manifest, data_dir);
  // Check every method spec before spending time on any run. With 'all', methods whose needs
  // (ranges, scans, odometry, map) the dataset lacks are skipped; named ones are errors.
  std::vector<std::string> runnable;
  for (const auto& m : methods) {
    const std::string missing = eval::missingNeeds(ds, m);
    if (!missing.empty()) {
      if (!all_methods)
        throw loc::ParamError("method '" + m + "' needs what dataset '" + ds.name +
                              "' lacks: " + missing);
      std::fprintf(stderr, "Skipping %s: the dataset has no %s\n", m.c_str(), missing.c_str());
      continue;
    }
    loc::Registry::builtin().create(
        m, eval::makeContext(ds, opt.seed),
        extraParams(loc::MethodSpec::parse(m).name, opt.config, opt.sets));
    runnable.push_back(m);
  }
  std::vector<eval::MethodSummary> summaries;
  for (const auto& m : runnable) {
    const auto extra = extraParams(loc::MethodSpec::parse(m).name, opt.config, opt.sets);
    summaries.push_back(eval::evaluateMethod(ds, m, opt.repeat, opt.seed, extra, printProgress));
  }
  const std::string out = opt.out.empty() ? "runs/" + ds.name : opt.out;
  const eval::DatasetBounds bounds = eval::computeBounds(ds);
  eval::writeRunDirectory(out, ds, summaries, {manifest, data_dir, opt.seed, opt.repeat, bounds});
  std::cout << eval::formatTable(ds, summaries, bounds);
  std::cout << "Run directory: " << out << "\n";
  return 0;
}

void addCommon(CLI::App* cmd, CommonOptions& opt) {
  cmd->add_option("--dataset,-d", opt.dataset,
                  "dataset manifest (INI); looked up as given, then in the data directory, then "
                  "in the repository's datasets/")
      ->capture_default_str();
  cmd->add_option("--data-dir", opt.data_dir,
                  "folder of public datasets (default: $UWBLOC_DATA_DIR, else ../shared/datasets)");
  cmd->add_option("--out,-o", opt.out, "run directory to write (default: runs/<dataset>)");
  cmd->add_option("--seed", opt.seed, "random seed of the first run")->capture_default_str();
  cmd->add_option("--config", opt.config,
                  "INI file with one [method-name] section of parameters per method");
  cmd->add_option("--set", opt.sets, "override one parameter: method.key=value (repeatable)");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "uwbloc: UWB / LiDAR / odometry localisation. Replays recorded datasets through the "
      "estimators and compares them against ground truth."};
  app.require_subcommand(1);

  CommonOptions run_opt;
  std::string method = "uwb-ekf";
  auto* run = app.add_subcommand("run", "Run one method on a dataset and score it");
  addCommon(run, run_opt);
  run->add_option("--method,-m", method, "method spec, e.g. uwb-kf:q=0.1 (see 'uwbloc methods')")
      ->capture_default_str();

  CommonOptions cmp_opt;
  std::string methods = "all";
  auto* compare = app.add_subcommand(
      "compare", "Run several methods on one dataset and print the comparison table");
  addCommon(compare, cmp_opt);
  compare
      ->add_option("--methods,-m", methods,
                   "comma-separated method specs, or 'all' for every registered method")
      ->capture_default_str();
  compare->add_option("--repeat", cmp_opt.repeat, "runs per method (seeds seed, seed+1, ...)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);

  std::string format, source, import_out;
  data::HanyangImportParams hanyang;
  std::string import_data_dir;
  auto* import = app.add_subcommand(
      "import", "Convert a public dataset into a rawlog, a ground-truth file and a manifest");
  import
      ->add_option("format", format,
                   "source format: hanyang (one dynamic run folder), carmen (a .log or .log.gz) or "
                   "plaza (the Plaza folder)")
      ->required();
  import
      ->add_option("source", source,
                   "source folder (as given, or relative to the data directory), e.g. "
                   "hanyang_outdoor_uwb/LOS_TrajA_Case1")
      ->required();
  import->add_option("--out,-o", import_out, "output folder")->required();
  import->add_option("--data-dir", import_data_dir, "folder of public datasets");
  import->add_option("--tag-height", hanyang.tag_height, "hanyang: tag height [m]")
      ->capture_default_str();

  std::string scenario, sim_out;
  uint64_t sim_seed = 1;
  auto* sim = app.add_subcommand(
      "simulate",
      "Simulate a scenario: writes a rawlog, ground truth (TUM and time x y phi), "
      "anchors, map and a manifest");
  sim->add_option("--scenario,-s", scenario,
                  "scenario INI (as given, or in the repository's datasets/scenarios/)")
      ->required();
  sim->add_option("--out,-o", sim_out, "output folder")->required();
  sim->add_option("--seed", sim_seed, "random seed; the same seed gives byte-identical files")
      ->capture_default_str();

  data::AugmentRequest aug;
  std::string aug_out;
  auto* augment = app.add_subcommand(
      "augment", "Add simulated UWB ranges to a real LiDAR recording at its reference poses");
  augment->add_option("--rawlog,-r", aug.rawlog, "recording (rawlog)")->required();
  augment->add_option("--reference,-p", aug.reference, "reference poses: .tum, else 'time x y phi'")
      ->required();
  augment->add_option("--anchors,-a", aug.anchors_csv, "anchors CSV (id,x,y,z)")->required();
  augment->add_option("--out,-o", aug_out, "output folder")->required();
  augment->add_option("--scenario,-s", aug.scenario,
                      "take the [uwb] noise model from this scenario");
  augment->add_option("--map", aug.map,
                      "map for NLOS: a map file, or 'scans' to map the recording's own scans at "
                      "the reference poses (default: no NLOS)");
  augment->add_option("--seed", aug.seed, "random seed")->capture_default_str();
  augment
      ->add_option("--max-gap", aug.max_gap,
                   "no ranges where reference poses are further apart than this [s]")
      ->capture_default_str();

  int opt_runs = 30;
  optim::RunSettings opt_settings;
  uint64_t opt_seed = 1;
  std::string opt_list = "bas,pso,ga,ba,ibas,ibas-fixed,ibas-scaled";
  std::string fn_list = "f1_sphere,f2_schwefel_2.22,f3_step,f4_rastrigin,f5_griewank";
  auto* bench_opt = app.add_subcommand(
      "bench-optimizers", "The PF-IBAS paper's Table 2: optimisers on benchmark functions");
  bench_opt->add_option("--runs", opt_runs, "runs per cell")->capture_default_str();
  bench_opt->add_option("--population", opt_settings.population, "population")
      ->capture_default_str();
  bench_opt->add_option("--iterations", opt_settings.iterations, "iterations")
      ->capture_default_str();
  bench_opt->add_option("--step", opt_settings.initial_step, "initial step (BAS, IBAS)")
      ->capture_default_str();
  bench_opt->add_option("--optimizers", opt_list, "comma-separated optimisers")
      ->capture_default_str();
  bench_opt
      ->add_option("--functions", fn_list,
                   "comma-separated functions (also michalewicz, goldstein_price)")
      ->capture_default_str();
  bench_opt->add_option("--seed", opt_seed, "seed of the first run")->capture_default_str();
  int opt_dim = 30;
  bench_opt
      ->add_option("--dim", opt_dim, "dimensions of f1-f5 (the paper's Table 2: 30)")
      ->check(CLI::Range(1, 32))
      ->capture_default_str();

  auto* list = app.add_subcommand("methods", "List the methods with their parameters and defaults");

  CLI11_PARSE(app, argc, argv);
  try {
    if (*run) return runMethods(run_opt, {method});
    if (*compare) return runMethods(cmp_opt, splitMethods(methods), methods == "all");
    if (*import) {
      const std::string src = data::resolveInputPath(source, data::resolveDataDir(import_data_dir));
      if (format == "hanyang") {
        const auto s = data::importHanyang(src, import_out, hanyang);
        std::cout << "Imported " << s.ranges << " ranges from " << s.anchors << " anchors and "
                  << s.ground_truth_rows << " reference poses\nManifest: " << s.manifest << "\n";
      } else if (format == "plaza") {
        const auto s = data::importPlaza(src, import_out);
        std::cout << "Imported " << s.ranges << " ranges to " << s.anchors << " beacons and "
                  << s.ground_truth_rows << " reference poses\nManifest: " << s.manifest << "\n";
      } else if (format == "carmen") {
        const auto s = data::importCarmen(src, import_out);
        std::cout << "Imported " << s.ranges << " scans and " << s.ground_truth_rows
                  << " reference poses\nManifest: " << s.manifest << "\n";
      } else {
        std::cerr << "error: unknown import format '" << format
                  << "' (known: hanyang, carmen, plaza)\n";
        return 2;
      }
      return 0;
    }
    if (*sim) {
      const std::string path = data::resolveInputPath(scenario, "");
      const auto sc = data::loadScenario(path);
      for (const auto& w : sc.warnings) std::cerr << "warning: " << path << ": " << w << "\n";
      const auto manifest = data::writeSimulation(sc, sim_seed, sim_out);
      std::cout << "Simulated " << sc.name << " (" << sc.duration << " s, seed " << sim_seed
                << ")\nManifest: " << manifest << "\n";
      return 0;
    }
    if (*bench_opt) {
      auto split = [](const std::string& text) {
        std::vector<std::string> out;
        std::istringstream in(text);
        for (std::string item; std::getline(in, item, ',');)
          if (!item.empty()) out.push_back(item);
        return out;
      };
      const auto cells =
          eval::optimizerTable(split(opt_list), split(fn_list), opt_runs, opt_settings, opt_seed, opt_dim);
      std::printf("%d runs, population %d, %d iterations, initial step %g, f1-f5 in %d-D\n",
                  opt_runs, opt_settings.population, opt_settings.iterations,
                  opt_settings.initial_step, opt_dim);
      std::cout << eval::formatOptimizerTable(cells);
      return 0;
    }
    if (*augment) {
      const auto manifest = data::writeAugmented(aug, aug_out);
      std::cout << "Manifest: " << manifest << "\n";
      return 0;
    }
    if (*list) {
      for (const auto& m : loc::Registry::builtin().methods()) {
        std::cout << m.name << "\n    " << m.description << "\n";
        for (const auto& p : m.defaults)
          std::printf("    %-12s = %-8s %s\n", p.key.c_str(), p.value.c_str(), p.help.c_str());
      }
      std::cout << "Set parameters in the spec (uwb-kf:q=0.1,sigma=0.2), in a --config INI "
                   "section [uwb-kf], or with --set uwb-kf.q=0.1.\n";
      return 0;
    }
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
