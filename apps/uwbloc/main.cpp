// uwbloc: replay recorded UWB / LiDAR / odometry data through localisation methods and score
// them against ground truth. Parses the command line and dispatches to a subcommand class
// (libs/apps); every subcommand's work is in the libraries.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "uwbloc/apps/command.hpp"

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UWBLOC_LEAK_CHECKED 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define UWBLOC_LEAK_CHECKED 1
#endif

namespace {

// Ends the process once a command has finished: every file is written and closed by then, and
// the streams are flushed here. Skipping the static destructors of the ~190 shared libraries
// that MRPT and OpenCV bring in saves about 50 ms a run, as much as a short method's run. A
// sanitized build exits normally, so that its leak check still runs.
[[noreturn]] void leave(int code) {
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);
#ifdef UWBLOC_LEAK_CHECKED
  std::exit(code);
#else
  std::_Exit(code);
#endif
}

}  // namespace

int main(int argc, char** argv) {
  using namespace uwbloc::apps;
  CLI::App parser{
      "uwbloc: UWB / LiDAR / odometry localisation. Replays recorded datasets through the "
      "estimators and compares them against ground truth."};
  parser.require_subcommand(1);
  auto commands = allCommands();
  for (auto& c : commands) c->declare(parser);
  try {
    parser.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = parser.exit(e);
    return code == 0 ? kSuccess : kUsage;
  }
  int code = kUsage;
  try {
    for (auto& c : commands)
      if (c->chosen()) code = c->run();
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    code = kBadInput;
  }
  leave(code);
}
