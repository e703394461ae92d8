// Batch solve time of the range + odometry graph for 1k, 10k and 100k synthetic poses (ranges to
// 4 anchors per pose, odometry between consecutive poses), from a dead-reckoning start.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/localization/graph/range_graph.hpp"

using namespace uwbloc;

static void BM_BatchSolve(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const std::vector<uwb::Anchor> anchors{{1, {0, 0, 2}}, {2, {60, 0, 2}}, {3, {60, 60, 2}}, {4, {0, 60, 2}}};
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0, 1);
  // A lawn-mower path inside the anchors, 0.1 m per step.
  std::vector<Eigen::Vector3d> truth;
  Eigen::Vector3d p(5, 5, 0);
  for (int k = 0; k < n; ++k) {
    truth.push_back(p);
    const double turn = (k % 500 == 499) ? M_PI / 2 : 0.0;
    p = loc::composePose(p, {0.1, 0.0, turn});
    if (p.x() > 55 || p.x() < 5 || p.y() > 55 || p.y() < 5) p = loc::composePose(p, {0, 0, M_PI / 2});
  }
  double iterations = 0, rmse = 0;
  for (auto _ : state) {
    state.PauseTiming();
    loc::graph::RangeGraph gr;
    gr.setAnchors(anchors);
    Eigen::Vector3d dr = truth[0];
    gr.addPose(dr);
    for (int k = 1; k < n; ++k) {
      Eigen::Vector3d d = loc::relativePose(truth[static_cast<size_t>(k - 1)], truth[static_cast<size_t>(k)]);
      d += Eigen::Vector3d(0.01 * g(rng), 0.01 * g(rng), 0.002 * g(rng));
      dr = loc::composePose(dr, d);
      gr.addPose(dr);
      gr.addOdometry(k - 1, k, d);
    }
    for (int k = 0; k < n; ++k)
      for (const auto& a : anchors) {
        const Eigen::Vector3d t(truth[static_cast<size_t>(k)].x(), truth[static_cast<size_t>(k)].y(), 1.0);
        gr.addRange(k, a.id, (t - a.position).norm() + 0.1 * g(rng), Eigen::Vector3d(0, 0, 1.0));
      }
    loc::graph::RangeGraphParams params;
    params.odometry_sigma = {0.01, 0.01, 0.002};
    gr.build(params);
    state.ResumeTiming();
    const auto sol = gr.solve();
    state.PauseTiming();
    iterations = sol.iterations;
    double s = 0;
    for (int k = 0; k < n; ++k) s += (gr.pose(static_cast<size_t>(k)).head<2>() - truth[static_cast<size_t>(k)].head<2>()).squaredNorm();
    rmse = std::sqrt(s / n);
    state.ResumeTiming();
  }
  state.counters["iterations"] = iterations;
  state.counters["pose_rmse_m"] = rmse;
}
BENCHMARK(BM_BatchSolve)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->Iterations(1);

BENCHMARK_MAIN();
