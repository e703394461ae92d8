// uwbloc: replay recorded UWB / LiDAR / odometry data through localisation methods and score
// them against ground truth. Parses the command line and dispatches to a subcommand class
// (libs/apps); every subcommand's work is in the libraries.
#include <CLI/CLI.hpp>
#include <iostream>

#include "uwbloc/apps/command.hpp"

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
  try {
    for (auto& c : commands)
      if (c->chosen()) return c->run();
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kBadInput;
  }
  return kUsage;
}
