// Importers and readers on constructed files: CARMEN's corrected-pose copies and bad stamps,
// Plaza's odometry direction found from the data, timestamps that cannot be used, collapsed
// timestamps, and dead reckoning and particle filters that start at the reference's first time.
#include <gtest/gtest.h>
#include <matio.h>

#include <cmath>
#include <iomanip>
#include <optional>
#include <sstream>
#include <tuple>
#include <vector>

#include "test_helpers.hpp"
#include "uwbloc/dataset/carmen_import.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/dataset/plaza_import.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

using namespace uwbloc;

namespace {

// A FLASER line of 3 rays at time t with the corrected pose `c` (odometry fields = c, as the
// corrected logs write them).
std::string flaser(double t, const Eigen::Vector3d& c) {
  std::ostringstream s;
  s << "FLASER 3 1.0 2.0 3.0 " << c.x() << " " << c.y() << " " << c.z() << " " << c.x() << " "
    << c.y() << " " << c.z() << " " << t << " host " << t << "\n";
  return s.str();
}
std::string odom(double t, const Eigen::Vector3d& p) {
  std::ostringstream s;
  s << "ODOM " << p.x() << " " << p.y() << " " << p.z() << " 0 0 0 " << t << " host " << t << "\n";
  return s.str();
}

}  // namespace

TEST(Carmen, CorrectedPoseCopiesAndBadStampsAreDroppedAndCounted) {
  // The raw odometry drives along x at 1 m/s; the corrected poses sit 0.5 m to the side. After
  // each FLASER line, an ODOM copy of its corrected pose, stamped 0, 0.71 or -20.1.
  std::string log;
  const char* copy_stamps[] = {"0", "0.71", "-20.1", "4.6e-72"};
  for (int k = 0; k < 8; ++k) {
    const double t = 1.0 + k;
    log += odom(t - 0.5, {t - 0.5, 0.0, 0.0});
    log += odom(t, {t, 0.0, 0.0});
    const Eigen::Vector3d corrected(t, 0.5, 0.0);
    log += flaser(t, corrected);
    std::ostringstream copy;
    copy << "ODOM " << corrected.x() << " " << corrected.y() << " 0 0 0 0 " << copy_stamps[k % 4]
         << " host 0\n";
    log += copy.str();
  }
  log += odom(-3.0, {20.0, 0.0, 0.0});  // a negative stamp
  log += "ODOM nan 0 0 0 0 0 30.0 host 30.0\n";
  log += flaser(31.0, {std::nan(""), 0.0, 0.0});
  log += odom(4.0, {30.0, 0.0, 0.0});  // earlier than the last kept reading
  const auto dir = test::scratchDir();
  test::writeText(dir / "x.log", log);
  const auto s = data::importCarmen((dir / "x.log").string(), (dir / "out").string());
  EXPECT_EQ(s.scans, 8);
  EXPECT_EQ(s.skipped.at("odom_corrected_pose_copy"), 8);
  EXPECT_EQ(s.skipped.at("odom_negative_time"), 1);
  EXPECT_EQ(s.skipped.at("odom_out_of_order"), 1);
  EXPECT_EQ(s.skipped.at("odom_non_finite_pose"), 1);
  EXPECT_EQ(s.skipped.at("flaser_non_finite_pose"), 1);
  // What is left is the raw odometry: 15 increments of 0.5 m along x, in time order.
  const auto rec = data::readRawlog((dir / "out" / "carmen.rawlog").string());
  double x = 0.0, last_t = -1.0;
  int increments = 0;
  for (const auto& e : rec.events)
    if (const auto* o = std::get_if<loc::OdometryIncrement>(&e)) {
      EXPECT_NEAR(o->delta.x(), 0.5, 1e-6);
      EXPECT_NEAR(o->delta.y(), 0.0, 1e-6);
      EXPECT_GE(o->t, last_t);
      last_t = o->t;
      x += o->delta.x();
      ++increments;
    }
  EXPECT_EQ(increments, 15);
  EXPECT_NEAR(x, 7.5, 1e-6);
}

TEST(Carmen, AReadingCountThatIsNoCountIsAnErrorNamingTheLine) {
  // Found by fuzzing: a FLASER count of -34.2 was converted to size_t (undefined behaviour).
  const auto dir = test::scratchDir();
  const auto log = test::writeText(
      dir / "x.log", odom(1.0, {0, 0, 0}) + "FLASER -34.2 1 1 0 0 0 0 0 0 2.0 h 2.0\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importCarmen(log, (dir / "out").string()); },
      {log + ":2", "num_readings", "-34.2"});
}

TEST(Carmen, RaysAreAWholeFractionOf180DegreesApart) {
  // 180 rays are 1 degree apart from -90 (the last at +89), 181 rays 1 degree apart from -90 to
  // +90 inclusive, 360 rays 0.5 degree apart.
  for (const auto& [n, step_deg, last_deg] :
       {std::tuple{180, 1.0, 89.0}, std::tuple{181, 1.0, 90.0}, std::tuple{360, 0.5, 89.5}}) {
    std::ostringstream line;
    line << "FLASER " << n;
    for (int i = 0; i < n; ++i) line << " 2.0";
    line << " 1 2 0 1 2 0 1.0 host 1.0\n";
    const auto dir = test::scratchDir();
    test::writeText(dir / "x.log", odom(0.5, {1, 2, 0}) + line.str());
    data::importCarmen((dir / "x.log").string(), (dir / "out").string());
    const auto rec = data::readRawlog((dir / "out" / "carmen.rawlog").string());
    const loc::LaserScan* scan = nullptr;
    for (const auto& e : rec.events)
      if (const auto* s = std::get_if<loc::LaserScan>(&e)) scan = s;
    ASSERT_NE(scan, nullptr) << n;
    ASSERT_EQ(scan->ranges.size(), static_cast<size_t>(n));
    // The rawlog keeps a scan symmetric about the sensor's axis and turns the sensor instead.
    const double first = scan->sensor_pose.z() + scan->angle_min;
    EXPECT_NEAR(first * 180.0 / M_PI, -90.0, 1e-4) << n;
    EXPECT_NEAR(scan->angle_increment * 180.0 / M_PI, step_deg, 1e-5) << n;
    EXPECT_NEAR((first + (n - 1) * scan->angle_increment) * 180.0 / M_PI, last_deg, 1e-3) << n;
  }
}

TEST(Rawlog, NegativeAndOutOfOrderStampsAreRejectedAndCounted) {
  std::vector<loc::Event> events;
  for (int k = 0; k < 5; ++k) {
    uwb::Range r;
    r.t = 10.0 + k;
    r.anchor_id = 1;
    r.range = 3.0;
    events.emplace_back(r);
  }
  uwb::Range bad;
  bad.t = -20.1;
  bad.anchor_id = 1;
  bad.range = 3.0;
  events.emplace_back(bad);
  const auto dir = test::scratchDir();
  data::writeRawlog((dir / "r.rawlog").string(), events);
  const auto rec = data::readRawlog((dir / "r.rawlog").string());
  EXPECT_EQ(rec.events.size(), 5u);
  // MRPT stores the stamp unsigned: -20.1 s reads back as about 1.8e12 s.
  EXPECT_EQ(rec.counts.at("rejected_absurd_time"), 1);
  for (const auto& e : rec.events) EXPECT_GE(loc::eventTime(e), 0.0);
}

TEST(Dataset, CollapsedTimestampsAreFlagged) {
  std::vector<loc::Event> events;
  for (int k = 0; k < 200; ++k) {
    uwb::Range r;
    r.t = k < 100 ? 1.13486e9 : 1.13487e9;  // six significant digits: two distinct stamps
    r.anchor_id = 1 + k % 3;
    r.range = 3.0;
    events.emplace_back(r);
  }
  const auto w = data::collapsedTimeWarning(events);
  ASSERT_TRUE(w.has_value());
  EXPECT_NE(w->find("2 distinct stamps for 200 messages"), std::string::npos) << *w;
  for (size_t k = 0; k < events.size(); ++k) std::get<uwb::Range>(events[k]).t = 0.1 * k;
  EXPECT_FALSE(data::collapsedTimeWarning(events).has_value());
}

// A Plaza-layout folder whose odometry runs forward (sign +1) or backward (-1) against the
// reference's heading: the importer finds which, and dead reckoning then follows the reference.
class PlazaDirection : public ::testing::TestWithParam<double> {};

TEST_P(PlazaDirection, IsFoundFromTheData) {
  const double sign = GetParam();
  const auto dir = test::scratchDir();
  std::ostringstream dr, td, gt;
  // A loop: 0.5 m per 0.5 s, turning 0.02 rad per step.
  Eigen::Vector3d pose(2.0, 1.0, 0.3);
  gt << "0 " << pose.x() << " " << pose.y() << " " << pose.z() << "\n";
  for (int k = 1; k <= 400; ++k) {
    const double t = 0.5 * k, d = 0.5, dh = 0.02;
    pose = loc::composePose(pose, {d * std::cos(dh / 2), d * std::sin(dh / 2), dh});
    dr << t << " " << sign * d << " " << dh << "\n";
    gt << t << " " << pose.x() << " " << pose.y() << " " << pose.z() << "\n";
    td << t << " 0 " << 1 + k % 4 << " 10.0\n";
  }
  test::writeText(dir / "P_DR.txt", dr.str());
  test::writeText(dir / "P_TD.txt", td.str());
  test::writeText(dir / "P_GT.txt", gt.str());
  test::writeText(dir / "P_TL.txt", "1 0 0\n2 50 0\n3 50 50\n4 0 50\n");
  const auto s = data::importPlaza(dir.string(), (dir / "out").string());
  ASSERT_FALSE(s.notes.empty());
  EXPECT_NE(s.notes[0].find(sign > 0 ? "forward" : "backward"), std::string::npos) << s.notes[0];
  const auto ds = data::loadDataset(s.manifest, "");
  const auto run = eval::evaluateMethod(ds, "odom", 1, 1);
  EXPECT_LT(run.metrics.rmse_2d, 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Both, PlazaDirection, ::testing::Values(1.0, -1.0));

TEST(Plaza, AnIdOutsideTheIntegersIsAnErrorNamingTheLine) {
  // Found by fuzzing: a beacon id of 3e20 was converted to int (undefined behaviour).
  const auto dir = test::scratchDir();
  test::writeText(dir / "P_DR.txt", "1 0.1 0\n2 0.1 0\n");
  test::writeText(dir / "P_GT.txt", "1 0 0 0\n2 0.1 0 0\n");
  test::writeText(dir / "P_TL.txt", "1 0 0\n2 5 0\n");
  const auto td = test::writeText(dir / "P_TD.txt", "1 0 1 3.0\n1.5 0 3e20 4.0\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importPlaza(dir.string(), (dir / "out").string()); },
      {td + ":2", "beacon", "integer id", "3e+20"});
  test::writeText(dir / "P_TD.txt", "1 0 1 3.0\n1.5 0 2.5 4.0\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importPlaza(dir.string(), (dir / "out").string()); }, {td + ":2", "2.5"});
}

// GTSAM's layout: _DR.txt and _TD.txt, the reference and the beacons in a .mat (written here
// with libmatio). The import equals that of the all-text layout.
TEST(Plaza, TheMatLayoutImportsLikeTheTextLayout) {
  const auto dir = test::scratchDir();
  const auto txt = dir / "txt", mat = dir / "mat";
  std::filesystem::create_directories(txt);
  std::filesystem::create_directories(mat);
  std::ostringstream dr, td, gt;
  std::vector<double> gt_cols[4];
  Eigen::Vector3d pose(2.0, 1.0, 0.3);
  for (int k = 0; k <= 200; ++k) {
    const double t = 0.5 * k;
    if (k > 0) {
      pose = loc::composePose(pose, {0.5 * std::cos(0.01), 0.5 * std::sin(0.01), 0.02});
      dr << t << " 0.5 0.02\n";
      td << t << " 0 " << 1 + k % 4 << " " << 5.0 + 0.01 * k << "\n";
    }
    gt << std::setprecision(17) << t << " " << pose.x() << " " << pose.y() << " " << pose.z()
       << "\n";
    for (int c = 0; c < 4; ++c) gt_cols[c].push_back(c == 0 ? t : pose(c - 1));
  }
  for (const auto& d : {txt, mat}) {
    test::writeText(d / "P_DR.txt", dr.str());
    test::writeText(d / "P_TD.txt", td.str());
  }
  test::writeText(txt / "P_GT.txt", gt.str());
  test::writeText(txt / "P_TL.txt", "1 0 0\n2 50 0\n3 50 50\n4 0 50\n");
  {
    mat_t* file = Mat_CreateVer((mat / "P.mat").string().c_str(), nullptr, MAT_FT_MAT5);
    ASSERT_NE(file, nullptr);
    std::vector<double> gt_data;  // column-major
    for (const auto& c : gt_cols) gt_data.insert(gt_data.end(), c.begin(), c.end());
    size_t gt_dims[2] = {gt_cols[0].size(), 4};
    double tl_data[] = {1, 2, 3, 4, 0, 50, 50, 0, 0, 0, 50, 50};
    size_t tl_dims[2] = {4, 3};
    for (auto [name, dims, data] :
         {std::tuple{"GT", gt_dims, gt_data.data()}, std::tuple{"TL", tl_dims, tl_data}}) {
      matvar_t* v = Mat_VarCreate(name, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, data, 0);
      ASSERT_NE(v, nullptr);
      EXPECT_EQ(Mat_VarWrite(file, v, MAT_COMPRESSION_NONE), 0);
      Mat_VarFree(v);
    }
    Mat_Close(file);
  }
  const auto a =
      data::loadDataset(data::importPlaza(txt.string(), (dir / "a").string()).manifest, "");
  const auto s = data::importPlaza(mat.string(), (dir / "b").string());
  EXPECT_NE(s.notes.back().find("P.mat variable GT"), std::string::npos) << s.notes.back();
  const auto b = data::loadDataset(s.manifest, "");
  ASSERT_EQ(a.events.size(), b.events.size());
  ASSERT_EQ(a.ground_truth.size(), b.ground_truth.size());
  for (size_t k = 0; k < a.ground_truth.size(); ++k)
    EXPECT_LT((a.ground_truth[k].pose - b.ground_truth[k].pose).norm(), 1e-6) << k;
  EXPECT_EQ(a.anchors.size(), 4u);
  for (const auto& anchor : a.anchors)
    EXPECT_EQ(uwb::findAnchor(b.anchors, anchor.id)->position, anchor.position);
  EXPECT_NEAR(eval::evaluateMethod(a, "odom", 1, 1).metrics.rmse_2d,
              eval::evaluateMethod(b, "odom", 1, 1).metrics.rmse_2d, 1e-9);
  // A .mat without the reference: an error naming the file and the variable.
  std::filesystem::remove(mat / "P.mat");
  {
    mat_t* file = Mat_CreateVer((mat / "P.mat").string().c_str(), nullptr, MAT_FT_MAT5);
    double tl_data[] = {1, 0, 0};
    size_t tl_dims[2] = {1, 3};
    matvar_t* v = Mat_VarCreate("TL", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, tl_dims, tl_data, 0);
    Mat_VarWrite(file, v, MAT_COMPRESSION_NONE);
    Mat_VarFree(v);
    Mat_Close(file);
  }
  test::expectErrorMentions<data::InputError>(
      [&] { data::importPlaza(mat.string(), (dir / "c").string()); },
      {"P.mat", "no variable 'GT'"});
  test::writeText(mat / "P.mat", "not a mat file");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importPlaza(mat.string(), (dir / "d").string()); }, {"P.mat", "libmatio"});
}

namespace {
/// A context whose start pose, (1, 2) heading 0, is at t = 5 s.
loc::EstimatorContext startingAtFiveSeconds(std::vector<uwb::Anchor> anchors) {
  loc::EstimatorContext ctx;
  ctx.anchors = std::move(anchors);
  ctx.initial_pose = Eigen::Vector3d(1.0, 2.0, 0.0);
  ctx.initial_time = 5.0;
  return ctx;
}

/// 1 m straight ahead at each time; the last increment's estimate, if any.
std::optional<loc::PoseEstimate> metreAheadAt(loc::Estimator& e, std::vector<double> times) {
  std::optional<loc::PoseEstimate> out;
  for (double t : times) {
    loc::OdometryIncrement o;
    o.t = t;
    o.delta << 1.0, 0.0, 0.0;
    out = e.process(o);
  }
  return out;
}
}  // namespace

TEST(Odometry, DeadReckoningStartsAtTheFirstReferenceTime) {
  // Increments at or before the start pose's time brought the robot there: they are skipped.
  auto odom = loc::Registry::builtin().create("odom", startingAtFiveSeconds({{1, {0, 0, 0}}}));
  metreAheadAt(*odom, {4.0, 5.0, 6.0});
  const auto poses = odom->finishAll();
  EXPECT_EQ(odom->statistics().rejected.at("odometry_before_start"), 2);
  const auto last = metreAheadAt(*odom, {7.0});
  ASSERT_TRUE(last.has_value());
  EXPECT_NEAR(last->pose.x(), 3.0, 1e-12);  // 1 + the increments at 6 and 7
}

// The particle filters start from the start pose at its time as well: 3 m of odometry recorded
// before it would put the cloud 3 m ahead of a robot that ranges from where it stands.
TEST(Odometry, ParticleFiltersStartAtTheFirstReferenceTime) {
  const auto ctx = startingAtFiveSeconds({{1, {0, 0, 0}}, {2, {10, 0, 0}}, {3, {0, 10, 0}}});
  auto pf = loc::Registry::builtin().create("uwb-pf:calib=0,sigma=0.1", ctx);
  metreAheadAt(*pf, {3.0, 4.0, 5.0});
  for (int k = 0; k < 30; ++k)
    for (const auto& a : ctx.anchors) {
      uwb::Range r;
      r.t = 5.1 + 0.1 * k;
      r.anchor_id = a.id;
      r.range = (a.position - Eigen::Vector3d(1.0, 2.0, 0.0)).norm();
      pf->process(r);
    }
  const auto poses = pf->finishAll();
  ASSERT_FALSE(poses.empty());
  EXPECT_EQ(pf->statistics().rejected.at("odometry_before_start"), 3);
  EXPECT_LT((poses.back().pose.head<2>() - Eigen::Vector2d(1.0, 2.0)).norm(), 0.1);
}

TEST(Hanyang, RowsWithUnusableStampsOrPosesAreSkippedAndCounted) {
  const auto dir = test::scratchDir();
  const std::string header =
      "%time,field.stamp,field.id,field.x,field.y,field.z,field.distanceFromTag,field.rssi,"
      "field.rssi_fp\n";
  for (int id : {3, 5, 9}) {
    std::string rows = header;
    for (int k = 0; k < 5; ++k) {
      const std::string stamp =
          (id == 3 && k == 2) ? "nan" : std::to_string(1000000000LL * (k + 1));
      rows +=
          "0," + stamp + "," + std::to_string(id) + "," + std::to_string(id) + ",0,2,5.0,-80,-82\n";
    }
    test::writeText(dir / ("A" + std::to_string(id) + ".csv"), rows);
  }
  test::writeText(dir / "trajectory.csv",
                  "timestamp,x,y,z,heading_degrees\n1000000000,0,0,0,0\n2000000000,nan,0,0,0\n"
                  "3000000000,1,0,0,0\n");
  const auto s = data::importHanyang(dir.string(), (dir / "out").string());
  EXPECT_EQ(s.ranges, 14);
  EXPECT_EQ(s.skipped.at("range_non_finite_time"), 1);
  EXPECT_EQ(s.skipped.at("reference_non_finite_pose"), 1);
  EXPECT_EQ(s.ground_truth_rows, 2);
}
