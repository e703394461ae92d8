// The simulator: noise statistics, NLOS only where the line of sight is blocked, ray casting,
// dropouts, determinism, and the errors of bad scenario files.
#include <gtest/gtest.h>
#include <mrpt/maps/COccupancyGridMap2D.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lidar/mrpt_grid.hpp"
#include "test_helpers.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/dataset/world.hpp"

using namespace uwbloc;
using data::InputError;
using test::expectErrorMentions;
using test::writeText;

namespace {

std::string scenarioPath(const std::string& name) {
  return std::string(UWBLOC_SOURCE_DIR) + "/datasets/scenarios/" + name;
}

// Does the segment a-b cross the rectangle r? (Liang-Barsky clipping, independent of the grid.)
bool segmentHitsRect(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const loc::Rect& r) {
  double t0 = 0.0, t1 = 1.0;
  const Eigen::Vector2d d = b - a;
  const double p[4] = {-d.x(), d.x(), -d.y(), d.y()};
  const double q[4] = {a.x() - r.xmin, r.xmax - a.x(), a.y() - r.ymin, r.ymax - a.y()};
  for (int i = 0; i < 4; ++i) {
    if (std::abs(p[i]) < 1e-12) {
      if (q[i] < 0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0)
      t0 = std::max(t0, t);
    else
      t1 = std::min(t1, t);
    if (t0 > t1) return false;
  }
  return true;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

TEST(Simulator, LosResidualsHaveTheConfiguredMeanAndSigma) {
  // greenhouse_r2: bias 0.5 m, sigma 0.5 m, open field (no NLOS).
  const auto s = data::loadScenario(scenarioPath("greenhouse_r2.ini"));
  const auto sim = data::simulate(s, 11);
  double sum = 0, sum2 = 0;
  long n = 0;
  for (const auto& r : sim.range_truth) {
    ASSERT_FALSE(r.nlos);
    if (r.true_range + r.error <= 0.0) continue;  // clipped at zero: not Gaussian
    sum += r.error;
    sum2 += r.error * r.error;
    ++n;
  }
  const double mean = sum / n, sd = std::sqrt(sum2 / n - mean * mean);
  const double se_mean = 0.5 / std::sqrt(n), se_sd = 0.5 / std::sqrt(2.0 * n);
  std::printf(
      "[ SIM      ] %ld LOS ranges: mean %.4f (want 0.5 +- %.4f), std %.4f (want 0.5 +- %.4f)\n", n,
      mean, 3 * se_mean, sd, 3 * se_sd);
  EXPECT_NEAR(mean, 0.5, 3 * se_mean);
  EXPECT_NEAR(sd, 0.5, 3 * se_sd);
}

TEST(Simulator, NlosBiasOnlyOnOccludedSegments) {
  const auto s = data::loadScenario(scenarioPath("pfibas_room.ini"));
  const auto sim = data::simulate(s, 5);
  long nlos = 0, los = 0, disagree = 0;
  double nlos_sum = 0;
  for (size_t i = 0; i < sim.range_truth.size(); ++i) {
    const auto& r = sim.range_truth[i];
    const uwb::Anchor* a = uwb::findAnchor(s.anchors, r.anchor_id);
    const Eigen::Vector3d pose = data::TrajectorySampler(s.trajectory).pose(r.t - s.start_time);
    bool blocked = false;
    for (const auto& ob : s.obstacles)
      blocked |= segmentHitsRect(pose.head<2>(), a->position.head<2>(), ob);
    disagree += blocked != r.nlos;
    if (r.nlos) {
      ++nlos;
      nlos_sum += r.error;
    } else {
      ++los;
      EXPECT_LT(std::abs(r.error), 5 * s.uwb.sigma) << "LOS range with a bias at t=" << r.t;
    }
  }
  std::printf(
      "[ SIM      ] %ld NLOS, %ld LOS ranges; grid vs exact geometry disagree on %ld; "
      "mean NLOS error %.3f m\n",
      nlos, los, disagree, nlos_sum / std::max(nlos, 1L));
  EXPECT_GT(nlos, 50);
  // Cells are 5 cm: segments grazing an obstacle's corner may go either way.
  EXPECT_LT(static_cast<double>(disagree) / sim.range_truth.size(), 0.01);
  EXPECT_NEAR(nlos_sum / nlos, s.uwb.nlos_mean, 0.15);  // exponential bias, mean 0.5 m
}

TEST(Simulator, RayCastScanHitsAKnownWall) {
  const auto map = uwbloc::data::mapFromRectangles({0, 0, 10, 10}, {{6, 4, 7, 6}}, 0.05);
  uwbloc::data::LidarParams lidar = uwbloc::data::LidarParams::preset("sick_lms");
  lidar.sensor_pose << 0.1, 0.0, 0.0;
  const auto scan = uwbloc::data::castScan(map, {2.0, 5.0, 0.0}, lidar);
  ASSERT_EQ(scan.ranges.size(), 361u);
  const size_t ahead = 180, left = 360, right = 0;
  // Straight ahead: the obstacle's face at x = 6, from the sensor at x = 2.1.
  EXPECT_NEAR(scan.ranges[ahead], 3.9, 0.06);
  // Left: the wall at y = 10, 5 m away. Right: the wall at y = 0.
  EXPECT_NEAR(scan.ranges[left], 5.0, 0.06);
  EXPECT_NEAR(scan.ranges[right], 5.0, 0.06);
  EXPECT_TRUE(scan.valid[ahead]);
  EXPECT_NEAR(scan.angle_min + ahead * scan.angle_increment, 0.0, 1e-6);
}

TEST(Simulator, DropoutIntervalsHoldNoRanges) {
  const auto s = data::loadScenario(scenarioPath("agv_room.ini"));
  const auto sim = data::simulate(s, 3);
  long before = 0, inside = 0, imu = 0;
  for (const auto& e : sim.events) {
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      const double t = r->t - s.start_time;
      if (t >= 15.0 && t <= 17.0) ++inside;
      if (t >= 13.0 && t < 15.0) ++before;
    }
    imu += std::holds_alternative<loc::ImuSample>(e);
  }
  EXPECT_EQ(inside, 0);
  EXPECT_GT(before, 150);             // 3 anchors at 30 Hz for 2 s
  EXPECT_NEAR(imu, 60 * 150 + 1, 1);  // 150 Hz for 60 s
}

TEST(Simulator, SameSeedGivesByteIdenticalFiles) {
  const auto dir = test::scratchDir();
  const auto s = data::loadScenario(scenarioPath("pfibas_room.ini"));
  data::writeSimulation(s, 7, (dir / "a").string());
  data::writeSimulation(s, 7, (dir / "b").string());
  data::writeSimulation(s, 8, (dir / "c").string());
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir / "a")) {
    const auto name = entry.path().filename();
    EXPECT_EQ(slurp(entry.path()), slurp(dir / "b" / name)) << name;
    ++files;
  }
  EXPECT_GE(files, 8);
  EXPECT_NE(slurp(dir / "a" / "sim.rawlog"), slurp(dir / "c" / "sim.rawlog"));
}

TEST(Simulator, SecondTagRangesCarryItsId) {
  const auto s = data::loadScenario(scenarioPath("corridor.ini"));
  const auto sim = data::simulate(s, 2);
  long own = 0, other = 0, mobile = 0;
  for (const auto& e : sim.events)
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      own += r->tag_id == 0 && r->anchor_id < uwb::kMobileAnchorBase;
      other += r->tag_id == 1;
      mobile += r->anchor_id == uwb::kMobileAnchorBase + 1;
    }
  // Anchors 1, 2 at 20 Hz and 3 at 10 Hz over 90 s; staggering pushes the last instant of
  // anchors 2 and 3 past the end.
  EXPECT_EQ(own, (20 * 90 + 1) + 20 * 90 + 10 * 90);
  EXPECT_EQ(other, own);
  EXPECT_GT(mobile, 1500);
  // The second tag stands still during its pauses.
  EXPECT_NEAR((sim.tag2_ground_truth[200].pose - sim.tag2_ground_truth[500].pose).norm(), 0.0,
              1e-9);
}

TEST(Scenario, BadFilesNameTheProblem) {
  const auto dir = test::scratchDir();
  const std::string base =
      "[world]\nbounds = 0 0 10 10\nobstacle_1 = 4 4 6 6\n[anchors]\nanchor_1 = 0.5 0.5 1\n"
      "anchor_2 = 9.5 0.5 1\nanchor_3 = 0.5 9.5 1\n";
  const auto unknown =
      writeText(dir / "u.ini", base + "[trajectory]\nwaypoints = 1 1, 2 2\nspeeed = 1\n");
  expectErrorMentions<InputError>([&] { data::loadScenario(unknown); },
                                  {unknown + ":10", "unknown key 'speeed'"});
  const auto outside = writeText(dir / "o.ini", base + "[trajectory]\nwaypoints = 1 1, 12 2\n");
  expectErrorMentions<InputError>([&] { data::loadScenario(outside); },
                                  {outside + ":9", "waypoint (12, 2)", "outside the map"});
  const auto inside = writeText(dir / "i.ini", base + "[trajectory]\nwaypoints = 1 1, 5 5\n");
  expectErrorMentions<InputError>([&] { data::loadScenario(inside); },
                                  {inside + ":9", "waypoint (5, 5)", "inside an obstacle"});
  const auto none = writeText(dir / "n.ini", "[trajectory]\nwaypoints = 1 1, 2 2\n");
  expectErrorMentions<InputError>([&] { data::loadScenario(none); }, {none, "no anchors"});
  const auto bad_number = writeText(dir / "b.ini", base + "[trajectory]\nwaypoints = 1 1, 2 x\n");
  expectErrorMentions<InputError>([&] { data::loadScenario(bad_number); },
                                  {bad_number + ":9", "'x'"});
  // An anchor on a wall is a warning, not an error.
  const auto wall =
      writeText(dir / "w.ini", base + "anchor_4 = 5 5 1\n[trajectory]\nwaypoints = 1 1, 2 2\n");
  const auto s = data::loadScenario(wall);
  ASSERT_EQ(s.warnings.size(), 1u);
  EXPECT_NE(s.warnings[0].find("anchor 4"), std::string::npos);
}

TEST(Trajectory, TurnsInPlaceAndPauses) {
  data::TrajectorySpec spec;
  spec.waypoints = {{0, 0}, {2, 0}, {2, 2}};
  spec.closed = false;
  spec.speed = 1.0;
  spec.turn_rate = M_PI / 2;  // a quarter turn takes 1 s
  spec.pauses = {{0.5, 1.5}};
  const data::TrajectorySampler t(spec);
  EXPECT_NEAR(t.lapTime(), 5.0, 1e-12);                           // 2 s, turn 1 s, 2 s
  EXPECT_TRUE(t.pose(1.0).isApprox(Eigen::Vector3d(0.5, 0, 0)));  // paused at 0.5 m
  EXPECT_TRUE(t.pose(3.0).isApprox(Eigen::Vector3d(2, 0, 0)));    // end of leg 1
  EXPECT_NEAR(t.pose(3.5).z(), M_PI / 4, 1e-12);                  // halfway through the turn
  EXPECT_TRUE(t.pose(10.0).isApprox(Eigen::Vector3d(2, 2, M_PI / 2)));
}

TEST(OccupancyMap, LoadsRosYamlPngAndGridmap) {
  const auto dir = test::scratchDir();
  const auto yaml = loc::OccupancyMap::load(std::string(UWBLOC_SOURCE_DIR) + "/maps/office.yaml");
  auto check = [](const loc::OccupancyMap& m, const std::string& what) {
    EXPECT_TRUE(m.occupied({5.02, 1.0})) << what << ": inner wall";
    EXPECT_TRUE(m.occupied({2.5, 5.5})) << what << ": pillar";
    EXPECT_FALSE(m.occupied({2.0, 2.0})) << what << ": free floor";
    EXPECT_FALSE(m.occupied({5.02, 3.6})) << what << ": door";
    EXPECT_NEAR(m.bounds().xmax - m.bounds().xmin, 10.0, 0.06) << what;
    EXPECT_TRUE(m.segmentBlocked({2.0, 1.0}, {8.0, 1.0})) << what;
    EXPECT_FALSE(m.segmentBlocked({2.0, 3.6}, {8.0, 3.6})) << what;
  };
  check(yaml, "yaml+pgm");
  const auto gridmap = (dir / "office.gridmap.gz").string();
  yaml.save(gridmap);
  check(loc::OccupancyMap::load(gridmap), "gridmap");
  const auto png = (dir / "office.png").string();
  ASSERT_TRUE(loc::MrptGridAccess::grid(yaml).saveAsBitmapFile(png));
  check(loc::OccupancyMap::load(png, 0.05, {yaml.bounds().xmin, yaml.bounds().ymin}), "png");
  test::expectErrorMentions<std::runtime_error>(
      [&] { loc::OccupancyMap::load((dir / "none.png").string()); }, {"none.png", "not found"});
}

TEST(Simulator, PerAnchorRates) {
  const auto s = data::loadScenario(scenarioPath("corridor.ini"));  // rate 20 Hz, rate_3 = 10 Hz
  const auto sim = data::simulate(s, 1);
  std::map<int, long> own;
  for (const auto& e : sim.events)
    if (const auto* r = std::get_if<uwb::Range>(&e); r && r->tag_id == 0) ++own[r->anchor_id];
  EXPECT_NEAR(own[1], 20 * 90 + 1, 1);
  EXPECT_NEAR(own[3], 10 * 90 + 1, 1);
}
