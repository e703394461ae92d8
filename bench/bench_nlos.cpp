// NLOS model costs: training on 10 000 rows, and judging one range (the filters' per-range
// cost), for the boosted trees and the logistic regression. Synthetic rows with the shape of
// DW1000 data (received minus first-path power, first-path power, range), labelled with noise.
#include <benchmark/benchmark.h>

#include "nlos_synthetic.hpp"
#include "uwbloc/nlos/train.hpp"

using namespace uwbloc;

namespace {

nlos::TrainParams params(int kind) {
  nlos::TrainParams p;
  p.set = nlos::FeatureSet::kPower;
  p.kind = kind == 2 ? nlos::Model::Kind::kLogistic : nlos::Model::Kind::kTrees;
  p.objective = kind == 0 ? "density" : "logistic";
  return p;
}

// Arg: 0 trees-density, 1 trees-logistic, 2 logreg.
void BM_Train10k(benchmark::State& state) {
  const auto t = test::softNlosRows(10000, 1);
  const auto p = nlos::pointers(t);
  for (auto _ : state) benchmark::DoNotOptimize(nlos::train(p, params(static_cast<int>(state.range(0)))));
}
BENCHMARK(BM_Train10k)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_JudgeOneRange(benchmark::State& state) {
  const auto t = test::softNlosRows(10000, 1);
  const auto model = nlos::train(nlos::pointers(t), params(static_cast<int>(state.range(0))));
  uwb::Range r;
  r.range = 7.5;
  r.fp_power_dbm = -88.0;
  size_t i = 0;
  for (auto _ : state) {
    r.rx_power_dbm = -88.0 + static_cast<double>(i++ % 13);
    benchmark::DoNotOptimize(model.judge(nlos::sampleOf(r)));
  }
}
BENCHMARK(BM_JudgeOneRange)->Arg(0)->Arg(1)->Arg(2);

}  // namespace

BENCHMARK_MAIN();
