#include "uwbloc/evaluation/optimizer_table.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>

#include "uwbloc/evaluation/benchmark_functions.hpp"

namespace uwbloc::eval {

namespace {
// The paper's Table 2 means (only those the issue quotes; the rest of its table is not in the
// extracted text).
double paperValue(const std::string& opt, const std::string& fn) {
  static const std::map<std::pair<std::string, std::string>, double> v{
      {{"bas", "f1_sphere"}, 1.61e4},          {{"ibas", "f1_sphere"}, 6.78e-16},
      {{"ibas", "f2_schwefel_2.22"}, 1.25e-8}, {{"ibas", "f3_step"}, 1.62e-1},
      {{"ibas", "f4_rastrigin"}, 3.10e-10},    {{"ibas", "f5_griewank"}, 5.77e-10}};
  auto it = v.find({opt, fn});
  return it == v.end() ? NAN : it->second;
}
}  // namespace

std::vector<OptimizerCell> optimizerTable(const std::vector<std::string>& optimizers,
                                          const std::vector<std::string>& functions, int runs,
                                          const optim::RunSettings& settings, uint64_t seed,
                                          int dim) {
  std::vector<OptimizerCell> out;
  for (const auto& fn : functions) {
    const auto bench = optim::benchmark(fn, dim);
    for (const auto& name : optimizers) {
      auto opt = optim::makeOptimizer(name);
      std::vector<double> values;
      const auto t0 = std::chrono::steady_clock::now();
      for (int r = 0; r < runs; ++r) {
        optim::Rng rng(seed + static_cast<uint64_t>(r));
        values.push_back(opt->minimize(bench.f, bench.box, settings, rng).value);
      }
      const double secs =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      OptimizerCell c{opt->name(), fn};
      for (double v : values) c.mean += v / runs;
      for (double v : values) c.std += (v - c.mean) * (v - c.mean);
      c.std = runs > 1 ? std::sqrt(c.std / (runs - 1)) : 0.0;
      std::sort(values.begin(), values.end());
      if (!values.empty()) {
        const size_t m = values.size() / 2;
        c.median = values.size() % 2 ? values[m] : 0.5 * (values[m - 1] + values[m]);
        c.worst = values.back();
      }
      c.seconds_per_run = secs / runs;
      c.paper = dim == 30 ? paperValue(name, fn) : NAN;  // the paper's f1-f5 are 30-D
      out.push_back(c);
    }
  }
  return out;
}

std::string formatOptimizerTable(const std::vector<OptimizerCell>& cells) {
  std::string out;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%-18s %-12s %12s %12s %12s %12s %12s %14s\n", "function",
                "optimiser", "mean", "std", "median", "worst", "s/run", "paper mean");
  out += buf;
  for (const auto& c : cells) {
    char paper[32] = "-";
    if (std::isfinite(c.paper)) std::snprintf(paper, sizeof paper, "%.2e", c.paper);
    std::snprintf(buf, sizeof buf, "%-18s %-12s %12.3e %12.3e %12.3e %12.3e %12.5f %14s\n",
                  c.function.c_str(), c.optimizer.c_str(), c.mean, c.std, c.median, c.worst,
                  c.seconds_per_run, paper);
    out += buf;
  }
  return out;
}

}  // namespace uwbloc::eval
