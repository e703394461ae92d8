// The subcommands of the uwbloc application, each a class (as MRPT's apps library holds
// MonteCarloLocalization_App): it declares its options on the command-line parser, and runs
// from the parsed options by calling the libraries. The executable only parses and dispatches.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace uwbloc::apps {

/// Exit codes: 0 success, 1 bad input, 2 usage, 3 a run that produced no valid result.
enum ExitCode { kSuccess = 0, kBadInput = 1, kUsage = 2, kNoResult = 3 };

class Command {
 public:
  virtual ~Command() = default;
  /// Adds this subcommand and its options to `parser`.
  virtual void declare(CLI::App& parser) = 0;
  /// True when the parsed command line chose this subcommand.
  bool chosen() const;
  /// Runs it; returns the process's exit code. Bad input throws (the caller prints it).
  virtual int run() = 0;

 protected:
  CLI::App* subcommand_ = nullptr;  ///< set by declare()
};

/// Every subcommand, in the order `uwbloc --help` lists them.
std::vector<std::unique_ptr<Command>> allCommands();

}  // namespace uwbloc::apps
