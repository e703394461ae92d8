// `uwbloc methods` and `uwbloc bench-optimizers`.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "uwbloc/evaluation/optimizer_table.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::apps {

void BenchOptimizersCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "bench-optimizers", "The PF-IBAS paper's Table 2: optimisers on benchmark functions");
  auto* cmd = subcommand_;
  cmd->add_option("--runs", runs_, "runs per cell")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--population", settings_.population, "population")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--iterations", settings_.iterations, "iterations")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--step", settings_.initial_step, "initial step (BAS, IBAS)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--optimizers", optimizers_, "comma-separated optimisers")->capture_default_str();
  cmd->add_option("--functions", functions_,
                  "comma-separated functions (also michalewicz, goldstein_price)")
      ->capture_default_str();
  cmd->add_option("--seed", seed_, "seed of the first run")->capture_default_str();
  cmd->add_option("--dim", dim_, "dimensions of f1-f5 (the paper's Table 2: 30)")
      ->check(CLI::Range(1, 32))
      ->capture_default_str();
}

int BenchOptimizersCommand::run() {
  const auto cells = eval::optimizerTable(splitList(optimizers_), splitList(functions_), runs_,
                                          settings_, seed_, dim_);
  std::printf("%d runs, population %d, %d iterations, initial step %g, f1-f5 in %d-D\n", runs_,
              settings_.population, settings_.iterations, settings_.initial_step, dim_);
  std::cout << eval::formatOptimizerTable(cells);
  return kSuccess;
}

void MethodsCommand::declare(CLI::App& parser) {
  subcommand_ =
      parser.add_subcommand("methods", "List the methods with their parameters and defaults");
  subcommand_->add_flag("--limits", limits_,
                        "print the one table of limits every numeric parameter is checked "
                        "against, and the command-line limits");
}

int MethodsCommand::run() {
  if (limits_) {
    std::cout << "| parameter | range | why |\n|---|---|---|\n";
    for (const auto& l : loc::paramLimits())
      std::printf("| `%s` | %s%g, %g] | %s |\n", l.key, l.min_exclusive ? "(" : "[", l.min, l.max,
                  l.why);
    std::cout << "| `--repeat` | [1, 1000] | runs per method |\n"
                 "| `--seeds` (benchmark) | [1, 100] | |\n"
                 "| `--runs`, `--population`, `--iterations` (bench-optimizers) | [1, 1e5], "
                 "[1, 1e5], [1, 1e6] | |\n"
                 "| `--dim` (bench-optimizers) | [1, 32] | |\n"
                 "| `--max-memory` (run, compare) | a size such as `512M`, `4G` (default: half "
                 "of the machine's memory) | a run whose estimated memory exceeds it is refused "
                 "before it starts |\n"
                 "\nEvery other numeric parameter must be finite.\n";
    return kSuccess;
  }
  for (const auto& m : loc::Registry::builtin().methods()) {
    std::cout << m.name << "\n    " << m.description << "\n";
    for (const auto& p : m.defaults)
      std::printf("    %-12s = %-8s %s\n", p.key.c_str(), p.value.c_str(), p.help.c_str());
  }
  std::cout << "Set parameters in the spec (uwb-kf:q=0.1,sigma=0.2), in a --config INI section "
               "[uwb-kf], or with --set uwb-kf.q=0.1.\n";
  return kSuccess;
}

}  // namespace uwbloc::apps
