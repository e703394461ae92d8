// LiDAR localisation and LiDAR-aided NLOS rejection on the MRPT demo (fixed seeds), and the
// ray-cast detector on constructed segments.
#include <gtest/gtest.h>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/world.hpp"
#include "uwbloc/evaluation/nlos_score.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"

using namespace uwbloc;

namespace {
const data::Dataset& demo() {
  static const auto ds =
      data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  return ds;
}
}  // namespace

TEST(MrptDemo, LidarMclTracksWithinMrptsFigure) {
  // Tracking: start box GT +- 0.5 m / +- 20 deg, 300 particles, 10 seeds.
  const auto s = eval::evaluateMethod(demo(), "lidar-mcl", 10, 1);
  std::printf("[ LIDAR    ] lidar-mcl n=300: rmse_2d %.4f +- %.4f m over %d seeds, %.4f ms/step\n",
              s.metrics.rmse_2d, s.rmse_2d_std, s.runs, s.ms_per_step);
  EXPECT_LE(s.metrics.rmse_2d, 0.155);
  EXPECT_GT(s.metrics.coverage, 0.99);
}

TEST(MrptDemo, NlosRejectionFromTheLidarPose) {
  const auto pf = eval::evaluateMethod(demo(), "fused-pf", 10, 1);
  const auto naive = eval::evaluateMethod(demo(), "fused-naive", 10, 1);
  const auto lidar = eval::evaluateMethod(demo(), "lidar-mcl", 10, 1);
  std::printf(
      "[ FUSED    ] rmse_2d over 10 seeds: fused-pf %.4f +- %.4f, fused-naive %.4f +- %.4f, "
      "lidar-mcl %.4f\n",
      pf.metrics.rmse_2d, pf.rmse_2d_std, naive.metrics.rmse_2d, naive.rmse_2d_std,
      lidar.metrics.rmse_2d);
  EXPECT_LT(pf.metrics.rmse_2d, naive.metrics.rmse_2d);
  EXPECT_LT(pf.metrics.rmse_2d, lidar.metrics.rmse_2d);
  // Detector scores: beacon 1's ranges off by more than 0.5 m, and the good ranges.
  const auto b1 = eval::scoreNlos(demo(), pf.range_decisions, 0.5, 1);
  std::printf(
      "[ NLOS     ] beacon 1: %ld bad ranges, %ld good (all beacons); LiDAR-pose test recall "
      "%.3f false alarm %.3f; map ray-cast recall %.3f false alarm %.3f\n",
      b1.pose.bad, b1.pose.good, b1.pose.recall(), b1.pose.false_alarm(), b1.raycast.recall(),
      b1.raycast.false_alarm());
  EXPECT_GT(b1.pose.bad, 100);
  EXPECT_GE(b1.pose.recall(), 0.9);
  EXPECT_LE(b1.pose.false_alarm(), 0.05);
}

TEST(MrptDemo, GlobalInitialisationConverges) {
  // Uniform over the free cells, 10000 particles, seed 1: within N = 20 scans the error falls
  // below 0.5 m and stays there.
  const auto run = eval::runMethod(demo(), "lidar-mcl:init=global,n=10000", 1);
  const auto errors = eval::associate(run.trajectory, demo().ground_truth);
  long last_bad = -1;
  for (size_t i = 0; i < errors.size(); ++i)
    if (errors[i].e2d > 0.5) last_bad = static_cast<long>(i);
  std::printf("[ GLOBAL   ] converged after %ld scans (error < 0.5 m from then on)\n",
              last_bad + 1);
  EXPECT_LE(last_bad + 1, 20);
}

TEST(RayCastDetector, FlagsABlockedSegmentAndPassesAClearOne) {
  const auto map = uwbloc::data::mapFromRectangles({0, 0, 10, 10}, {{4.9, 2, 5.1, 8}}, 0.05);
  EXPECT_TRUE(map.segmentBlocked({2, 5}, {8, 5}));           // through the wall
  EXPECT_FALSE(map.segmentBlocked({2, 1}, {8, 1}));          // below it
  EXPECT_FALSE(map.segmentBlocked({2, 5}, {2, 9}));          // same side
  EXPECT_FALSE(map.segmentBlocked({2, 5}, {5.0, 5}, 0.15));  // ends on the wall: its cell skipped
}
