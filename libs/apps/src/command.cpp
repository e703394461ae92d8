#include "uwbloc/apps/command.hpp"

#include <CLI/CLI.hpp>

#include "commands.hpp"

namespace uwbloc::apps {

bool Command::chosen() const { return subcommand_ && subcommand_->parsed(); }

std::vector<std::unique_ptr<Command>> allCommands() {
  std::vector<std::unique_ptr<Command>> out;
  out.push_back(std::make_unique<RunMethodsCommand>(false));
  out.push_back(std::make_unique<RunMethodsCommand>(true));
  out.push_back(std::make_unique<ImportCommand>());
  out.push_back(std::make_unique<SimulateCommand>());
  out.push_back(std::make_unique<AugmentCommand>());
  out.push_back(std::make_unique<BenchmarkCommand>());
  out.push_back(std::make_unique<BenchOptimizersCommand>());
  out.push_back(std::make_unique<MethodsCommand>());
  return out;
}

}  // namespace uwbloc::apps
