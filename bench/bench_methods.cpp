// Per-step cost of every registered method on the MRPT UWB demo. Reports the time of a whole
// replay, and as counters the cost per produced pose (ms/step) and the real-time factor.
#include <benchmark/benchmark.h>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

namespace {

const uwbloc::data::Dataset& demo() {
  static const auto ds =
      uwbloc::data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  return ds;
}

void replay(benchmark::State& state, const std::string& spec) {
  const auto& ds = demo();
  double busy = 0.0;
  long steps = 0;
  for (auto _ : state) {
    const auto run = uwbloc::eval::runMethod(ds, spec, 1);
    busy += run.processing_seconds;
    steps += static_cast<long>(run.trajectory.size());
    benchmark::DoNotOptimize(run.trajectory.data());
  }
  state.counters["ms_per_step"] = steps ? 1e3 * busy / steps : 0.0;
  state.counters["steps"] = static_cast<double>(steps) / state.iterations();
  state.counters["xRT"] = busy > 0 ? ds.duration() * state.iterations() / busy : 0.0;
}

const bool registered = [] {
  for (const auto& name : uwbloc::loc::Registry::builtin().names())
    benchmark::RegisterBenchmark(("mrpt_demo/" + name).c_str(), replay, name)
        ->Unit(benchmark::kMillisecond);
  // The PF-IBAS paper's Table 3 particle counts, and the graph back end online (a fixed-lag
  // window of 10 vertices).
  for (const std::string spec : {"pf-sir:n=50", "pf-sir:n=100", "pf-ibas+graph:window=10"})
    benchmark::RegisterBenchmark(("mrpt_demo/" + spec).c_str(), replay, spec)
        ->Unit(benchmark::kMillisecond);
  return true;
}();

}  // namespace

BENCHMARK_MAIN();
