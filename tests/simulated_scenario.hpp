// Simulates a committed scenario into a scratch folder and loads it (tests that need the
// simulator link uwbloc_dataset).
#pragma once

#include <string>

#include "test_helpers.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/simulator.hpp"

namespace uwbloc::test {

/// `scenario` is a file name under datasets/scenarios/ without ".ini".
inline data::Dataset simulatedScenario(const std::string& scenario, uint64_t seed) {
  const auto dir = scratchDir() / (scenario + "_" + std::to_string(seed));
  const auto s = data::loadScenario(std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/" +
                                    scenario + ".ini");
  return data::loadDataset(data::writeSimulation(s, seed, dir.string()), "");
}

}  // namespace uwbloc::test
