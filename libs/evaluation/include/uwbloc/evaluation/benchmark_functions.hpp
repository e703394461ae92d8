// The optimiser benchmark functions of the PF-IBAS paper's Table 1 and two 2-D classics, for
// `uwbloc bench-optimizers` and the optimiser tests. Not part of any estimator.
#pragma once

#include <string>
#include <vector>

#include "uwbloc/localization/optim/optimizers.hpp"

namespace uwbloc::optim {

/// A benchmark function with its search box and known minimum.
struct Benchmark {
  std::string name;
  Box box;
  double minimum = 0.0;  ///< known minimum (Michalewicz: the BAS reference's value)
  Objective f;
};

/// f1 sphere, f2 Schwefel 2.22, f3 step, f4 Rastrigin, f5 Griewank (30-D, the paper's Table 1
/// ranges), michalewicz (2-D over [-6,-1]x[0,2], m = 10) and goldstein_price (2-D, [-2,2]^2).
std::vector<Benchmark> benchmarks(int dim = 30);
Benchmark benchmark(const std::string& name, int dim = 30);

}  // namespace uwbloc::optim
