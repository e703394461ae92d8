#include "uwbloc/apps/command.hpp"

#include <CLI/CLI.hpp>
#include <cctype>
#include <sstream>

#include "commands.hpp"

namespace uwbloc::apps {

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string item; std::getline(in, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

std::vector<std::string> splitMethodSpecs(const std::string& list) {
  std::vector<std::string> out;
  for (const auto& item : splitList(list)) {
    const auto eq = item.find('=');
    if (eq != std::string::npos && eq < item.find(':') && !out.empty())
      out.back() += "," + item;
    else
      out.push_back(item);
  }
  return out;
}

std::string safeName(const std::string& name, const std::string& fallback) {
  std::string out;
  for (char c : name)
    out += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
  return out.empty() ? fallback : out;
}

bool Command::chosen() const { return subcommand_ && subcommand_->parsed(); }

std::vector<std::unique_ptr<Command>> allCommands() {
  std::vector<std::unique_ptr<Command>> out;
  out.push_back(std::make_unique<RunMethodsCommand>(false));
  out.push_back(std::make_unique<RunMethodsCommand>(true));
  out.push_back(std::make_unique<ImportCommand>());
  out.push_back(std::make_unique<ExportCommand>());
  out.push_back(std::make_unique<SimulateCommand>());
  out.push_back(std::make_unique<AugmentCommand>());
  out.push_back(std::make_unique<BenchmarkCommand>());
  out.push_back(std::make_unique<SensitivityCommand>());
  out.push_back(std::make_unique<BenchOptimizersCommand>());
  out.push_back(std::make_unique<NlosCommand>());
  out.push_back(std::make_unique<CalibrateCommand>());
  out.push_back(std::make_unique<EvaluateCommand>());
  out.push_back(std::make_unique<SweepCommand>());
  out.push_back(std::make_unique<MethodsCommand>());
  return out;
}

}  // namespace uwbloc::apps
