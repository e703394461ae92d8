// The PF-IBAS paper's Table 2: optimisers on the benchmark functions, several seeded runs each.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "uwbloc/localization/optim/optimizers.hpp"

namespace uwbloc::eval {

struct OptimizerCell {
  std::string optimizer, function;
  double mean = 0.0, std = 0.0, median = 0.0, worst = 0.0, seconds_per_run = 0.0;
  double paper = NAN;  ///< the paper's mean, where it reports one
};

/// Runs every optimiser on every function `runs` times (seeds seed, seed+1, ...); f1-f5 in
/// `dim` dimensions (the paper: 30), the 2-D functions in 2.
std::vector<OptimizerCell> optimizerTable(const std::vector<std::string>& optimizers,
                                          const std::vector<std::string>& functions, int runs,
                                          const optim::RunSettings& settings, uint64_t seed,
                                          int dim = 30);

std::string formatOptimizerTable(const std::vector<OptimizerCell>& cells);

}  // namespace uwbloc::eval
