// Landmark extraction, the eq. (5) observation model's Jacobians, association, and ICP on a
// synthetic scan.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "uwbloc/dataset/world.hpp"
#include "uwbloc/localization/lidar/landmarks.hpp"
#include "uwbloc/localization/lidar/occupancy_map.hpp"
#include "uwbloc/localization/registry.hpp"

using namespace uwbloc::loc;

namespace {

template <class F>
Eigen::MatrixXd numericJacobian(F f, const Eigen::VectorXd& x, double h = 1e-6) {
  const Eigen::VectorXd y0 = f(x);
  Eigen::MatrixXd j(y0.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd a = x, b = x;
    a(i) += h;
    b(i) -= h;
    j.col(i) = (f(a) - f(b)) / (2 * h);
  }
  return j;
}

}  // namespace

class ObservationJacobians : public ::testing::TestWithParam<int> {};

TEST_P(ObservationJacobians, MatchNumeric) {
  const Eigen::Vector3d poses[] = {{1, 2, 0.3}, {-4, 0.5, -2.9}, {0, 0, M_PI / 2}};
  const Eigen::Vector2d marks[] = {{3, -1}, {-6, 4}, {0.5, 2}};
  const Eigen::Vector3d pose = poses[GetParam()];
  const Eigen::Vector2d mark = marks[GetParam()];
  for (bool rb : {false, true}) {
    Eigen::Matrix<double, 2, 3> jp;
    Eigen::Matrix2d jm;
    auto obs = [rb](const Eigen::Vector3d& p, const Eigen::Vector2d& m) -> Eigen::VectorXd {
      return rb ? observeLandmarkRangeBearing(p, m) : observeLandmarkXy(p, m);
    };
    if (rb)
      observeLandmarkRangeBearing(pose, mark, &jp, &jm);
    else
      observeLandmarkXy(pose, mark, &jp, &jm);
    const auto njp = numericJacobian([&](const Eigen::VectorXd& p) { return obs(p, mark); }, pose);
    const auto njm = numericJacobian([&](const Eigen::VectorXd& m) { return obs(pose, m); }, mark);
    EXPECT_LT((jp - njp).cwiseAbs().maxCoeff(), 1e-6)
        << "case " << GetParam() << (rb ? " range-bearing" : " xy");
    EXPECT_LT((jm - njm).cwiseAbs().maxCoeff(), 1e-6)
        << "case " << GetParam() << (rb ? " range-bearing" : " xy");
  }
  // Eq. (5) by hand for the first case: R(0.3)^T ((3,-1) - (1,2)).
  if (GetParam() == 0) {
    const double c = std::cos(0.3), s = std::sin(0.3);
    EXPECT_TRUE(
        observeLandmarkXy(pose, mark).isApprox(Eigen::Vector2d(c * 2 + s * -3, -s * 2 + c * -3)));
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, ObservationJacobians, ::testing::Range(0, 3));

TEST(Landmarks, CornersOfARoomAndConsistentAssociation) {
  const auto map = uwbloc::data::mapFromRectangles({0, 0, 6, 4}, {}, 0.02);
  auto lidar = uwbloc::data::LidarParams::preset("rplidar_a2");
  lidar.rays = 720;
  LandmarkExtractionParams p;
  LandmarkMap lm;
  const Eigen::Vector2d room_corners[] = {{0, 0}, {6, 0}, {6, 4}, {0, 4}};
  for (const Eigen::Vector3d& pose :
       {Eigen::Vector3d(2.0, 1.5, 0.4), Eigen::Vector3d(3.5, 2.2, -1.0)}) {
    const auto scan = uwbloc::data::castScan(map, pose, lidar);
    const auto lines = extractLines(scan, p);
    EXPECT_GE(lines.size(), 4u);
    const auto corners = extractCorners(lines, p);
    int matched = 0;
    for (const auto& c : corners) {
      Eigen::Vector2d world = pose.head<2>() + Eigen::Rotation2Dd(pose.z()) * c;
      for (const auto& rc : room_corners) matched += (world - rc).norm() < 0.1;
      lm.integrate(pose, Eigen::Matrix3d::Identity() * 1e-4, c,
                   Eigen::Matrix2d::Identity() * 0.0025);
    }
    EXPECT_GE(matched, 3) << "pose " << pose.transpose();
  }
  // Seen from two poses, each room corner is one landmark, not two.
  int near_corners = 0;
  for (const auto& l : lm.landmarks())
    for (const auto& rc : room_corners) near_corners += (l.position - rc).norm() < 0.1;
  EXPECT_LE(near_corners, 4);
  EXPECT_GE(near_corners, 3);
  bool reobserved = false;
  for (const auto& l : lm.landmarks()) reobserved |= l.observations >= 2;
  EXPECT_TRUE(reobserved);
}

TEST(LidarIcp, RecoversAKnownTransform) {
  // Two scans of an L-shaped room 0.30 m and 0.1 rad apart; the odometry guess is off by
  // (0.1 m, -0.05 m, 0.05 rad).
  const auto map =
      uwbloc::data::mapFromRectangles({0, 0, 8, 6}, {{4, 3, 8, 6}, {1, 1, 1.5, 1.8}}, 0.02);
  auto lidar = uwbloc::data::LidarParams::preset("sick_lms");
  const Eigen::Vector3d a(2.0, 2.0, 0.2), truth(0.30, 0.05, 0.1);
  const Eigen::Vector3d b = composePose(a, truth);
  EstimatorContext ctx;
  ctx.initial_pose = a;
  auto icp = Registry::builtin().create("lidar-icp", ctx);
  LaserScan s1 = uwbloc::data::castScan(map, a, lidar), s2 = uwbloc::data::castScan(map, b, lidar);
  s1.t = 1.0;
  s2.t = 2.0;
  ASSERT_TRUE(icp->process(s1));
  OdometryIncrement guess;
  guess.t = 1.5;
  guess.delta = truth + Eigen::Vector3d(0.1, -0.05, 0.05);
  icp->process(guess);
  const auto est = icp->process(s2);
  ASSERT_TRUE(est);
  const Eigen::Vector3d rel = relativePose(a, est->pose);
  EXPECT_NEAR(rel.x(), truth.x(), 0.02);
  EXPECT_NEAR(rel.y(), truth.y(), 0.02);
  EXPECT_NEAR(rel.z(), truth.z(), 0.01);
}
