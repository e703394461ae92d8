// Per-step cost of every registered method on the MRPT UWB demo, and of the multi-tag methods
// on the simulated three-tag room. Reports the time of a whole replay, and as counters the cost
// per produced pose (ms/step) and the real-time factor.
#include <benchmark/benchmark.h>

#include <filesystem>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

namespace {

const uwbloc::data::Dataset& demo() {
  static const auto ds =
      uwbloc::data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  return ds;
}

// The three-tag room (datasets/scenarios/multitag_room.ini), simulated once with seed 1.
const uwbloc::data::Dataset& multitagRoom() {
  static const auto ds = [] {
    const auto dir = std::filesystem::temp_directory_path() / "uwbloc_bench_multitag_room";
    const auto s = uwbloc::data::loadScenario(std::string(UWBLOC_SOURCE_DIR) +
                                              "/datasets/scenarios/multitag_room.ini");
    return uwbloc::data::loadDataset(uwbloc::data::writeSimulation(s, 1, dir.string()), "");
  }();
  return ds;
}

void replayOn(benchmark::State& state, const uwbloc::data::Dataset& ds, const std::string& spec) {
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

void replay(benchmark::State& state, const std::string& spec) { replayOn(state, demo(), spec); }

void replayMultitag(benchmark::State& state, const std::string& spec) {
  replayOn(state, multitagRoom(), spec);
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
  for (const std::string spec :
       {"uwb-multitag", "uwb-multitag:smooth=false", "uwb-ekf", "uwb-ekf:tags=primary", "uwb-ckf",
        "uwb-srukf", "uwb-shkf", "federated-ekf", "uwb-gn", "uwb-gn:tags=primary", "uwb-kf",
        "uwb-kf:tags=primary", "uwb-pf", "graph-uwb-odom"})
    benchmark::RegisterBenchmark(("multitag_room/" + spec).c_str(), replayMultitag, spec)
        ->Unit(benchmark::kMillisecond);
  return true;
}();

}  // namespace

BENCHMARK_MAIN();
