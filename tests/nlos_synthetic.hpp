// Synthetic labelled ranges for the NLOS model's tests and benchmark.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "uwbloc/nlos/table.hpp"

namespace uwbloc::test {

/// Rows whose NLOS odds grow smoothly with received minus first-path power pd (uniform in
/// [0, 12] dB): P(NLOS) = 1 / (1 + exp(-(pd - 6))); NLOS ranges read 0.5 m long.
inline nlos::Table softNlosRows(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  nlos::Table t;
  for (int i = 0; i < n; ++i) {
    nlos::Sample s;
    const double pd = 12.0 * u(rng);
    s.label = u(rng) < 1.0 / (1.0 + std::exp(-(pd - 6.0)));
    s.fp_power_dbm = -90.0 + 10.0 * u(rng);
    s.rx_power_dbm = s.fp_power_dbm + pd;
    s.true_range = 2.0 + 20.0 * u(rng);
    s.range = s.true_range + (s.label ? 0.5 : 0.0);
    t.rows.push_back(s);
  }
  return t;
}

}  // namespace uwbloc::test
