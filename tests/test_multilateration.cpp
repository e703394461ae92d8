// Multilateration: exact agreement without noise, efficiency against the Cramér-Rao bound,
// degenerate geometry, height projection, the range model's Jacobian, and the rigid fit of several
// tags' points to their lever arms.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "uwbloc/uwb/multilateration.hpp"
#include "uwbloc/uwb/range_model.hpp"
#include "uwbloc/uwb/rigid_fit.hpp"

using namespace uwbloc::uwb;

namespace {

std::vector<PlanarRange> rangesTo(const std::vector<Eigen::Vector2d>& anchors,
                                  const Eigen::Vector2d& p, double sigma = 0.1) {
  std::vector<PlanarRange> out;
  for (const auto& a : anchors) out.push_back({a, (p - a).norm(), sigma});
  return out;
}

struct Geometry {
  std::vector<Eigen::Vector2d> anchors;
  Eigen::Vector2d target;
};

std::vector<Geometry> geometries() {
  return {
      {{{0, 0}, {6, 0}, {6, 6}, {0, 6}}, {1.3, 4.2}},                    // greenhouse square
      {{{0, 0}, {0, 8}, {8, 0}}, {2.5, 2.5}},                            // PF-IBAS room
      {{{0, 0}, {7, 0}, {0, 5}}, {6.0, 4.0}},                            // AGV room, corner
      {{{-1.79, -4.55}, {4.71, -4.33}, {4.7023, 0.3185}}, {10.0, 2.0}},  // MRPT demo, outside
      {{{0, 0}, {10, 0}, {10, 10}, {0, 10}, {5, 12}}, {-3.0, 7.0}},      // five, outside hull
  };
}

}  // namespace

class NoiseFree : public ::testing::TestWithParam<int> {};

TEST_P(NoiseFree, SolversAgreeExactly) {
  const Geometry g = geometries()[static_cast<size_t>(GetParam())];
  const auto r = rangesTo(g.anchors, g.target);
  const Fix ls = solveLinearLS(r), gn = solveGaussNewton(r), chan = solveChan(r);
  for (const Fix* f : {&ls, &gn, &chan}) {
    ASSERT_TRUE(f->ok()) << "case " << GetParam() << ": " << toString(f->status);
    EXPECT_NEAR((f->position - g.target).norm(), 0.0, 1e-9) << "case " << GetParam();
    EXPECT_NEAR(f->residual_norm, 0.0, 1e-8) << "case " << GetParam();
  }
  if (g.anchors.size() == 3) {
    const Fix three = solveThreeAnchors(r);
    ASSERT_TRUE(three.ok());
    EXPECT_NEAR((three.position - g.target).norm(), 0.0, 1e-9) << "case " << GetParam();
  }
}

INSTANTIATE_TEST_SUITE_P(Geometries, NoiseFree, ::testing::Range(0, 5));

TEST(Multilateration, GaussNewtonReachesCramerRaoBound) {
  // 1000 seeded trials, sigma = 0.1 m: RMSE within 10 % of sqrt(trace(sigma^2 (H^T H)^-1)).
  const std::vector<Eigen::Vector2d> anchors{{0, 0}, {6, 0}, {6, 6}, {0, 6}};
  const Eigen::Vector2d p(1.5, 4.0);
  const double sigma = 0.1;
  const double bound = std::sqrt(crlb2d(rangesTo(anchors, p, sigma), p)->trace());
  std::mt19937_64 rng(42);
  std::normal_distribution<double> noise(0.0, sigma);
  double se_gn = 0, se_ls = 0, se_chan = 0;
  const int trials = 1000;
  for (int i = 0; i < trials; ++i) {
    auto r = rangesTo(anchors, p, sigma);
    for (auto& x : r) x.range += noise(rng);
    se_gn += (solveGaussNewton(r).position - p).squaredNorm();
    se_ls += (solveLinearLS(r).position - p).squaredNorm();
    se_chan += (solveChan(r).position - p).squaredNorm();
  }
  const double gn = std::sqrt(se_gn / trials), ls = std::sqrt(se_ls / trials),
               chan = std::sqrt(se_chan / trials);
  std::printf(
      "[ CRLB     ] sqrt(CRLB) %.4f m; RMSE GN %.4f (%.3f), LS %.4f (%.3f), Chan %.4f (%.3f)\n",
      bound, gn, gn / bound, ls, ls / bound, chan, chan / bound);
  EXPECT_NEAR(gn / bound, 1.0, 0.10);
  EXPECT_NEAR(chan / bound, 1.0, 0.10);
}

TEST(Multilateration, DegenerateGeometryIsReported) {
  const std::vector<Eigen::Vector2d> collinear{{0, 0}, {5, 0}, {10, 0}};
  const auto r = rangesTo(collinear, {3, 4});
  EXPECT_EQ(solveLinearLS(r).status, FixStatus::kDegenerate);
  EXPECT_EQ(solveGaussNewton(r).status, FixStatus::kDegenerate);
  EXPECT_EQ(solveChan(r).status, FixStatus::kDegenerate);
  EXPECT_EQ(solveThreeAnchors(r).status, FixStatus::kDegenerate);
  const std::vector<Eigen::Vector2d> two{{0, 0}, {5, 0}};
  EXPECT_EQ(solveLinearLS(rangesTo(two, {3, 4})).status, FixStatus::kTooFewAnchors);
  const std::vector<Eigen::Vector2d> coincident{{1, 1}, {1, 1}, {1, 1}};
  EXPECT_EQ(solveGaussNewton(rangesTo(coincident, {3, 4})).status, FixStatus::kDegenerate);
}

TEST(RangeModel, HeightProjection) {
  EXPECT_DOUBLE_EQ(*projectToPlane(5.0, 3.0), 4.0);  // eq. (3), 3-4-5
  EXPECT_DOUBLE_EQ(*projectToPlane(3.0, -3.0), 0.0);
  EXPECT_FALSE(projectToPlane(2.0, 3.0).has_value());  // shorter than the height difference
  EXPECT_FALSE(projectToPlane(NAN, 1.0).has_value());
}

TEST(RangeModel, JacobianMatchesNumeric) {
  const Eigen::Vector3d anchor(4.0, -2.0, 2.1), tag(0.16, 0.05, 1.12);
  for (const Eigen::Vector3d& pose :
       {Eigen::Vector3d(1.0, 2.0, 0.3), Eigen::Vector3d(-3, 0.5, -2.8),
        Eigen::Vector3d(3.9, -2.1, 1.57)}) {
    Eigen::RowVector3d j;
    const double h = predictRange(pose, tag, anchor, &j);
    EXPECT_NEAR(h, (tagPosition(pose, tag) - anchor).norm(), 1e-12);
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d(k) = 1e-6;
      const double num =
          (predictRange(pose + d, tag, anchor) - predictRange(pose - d, tag, anchor)) / 2e-6;
      EXPECT_NEAR(j(k), num, 1e-6) << "component " << k;
    }
  }
}

namespace {

// The points of `body` placed by `pose`, measured with isotropic std `sigma`.
std::vector<BodyPoint> placed(const uwbloc::Pose2& pose, const std::vector<Eigen::Vector2d>& body,
                              double sigma) {
  std::vector<BodyPoint> out;
  for (const auto& b : body)
    out.push_back(
        {b, uwbloc::transformPoint(pose, b), sigma * sigma * Eigen::Matrix2d::Identity()});
  return out;
}

}  // namespace

TEST(RigidFit, RecoversThePoseExactlyAtAnyHeading) {
  const std::vector<Eigen::Vector2d> three = {{-0.07, -0.14}, {-0.075, 0.14}, {0.20, 0.145}};
  for (double deg : {-179.9, -120.0, -45.0, 0.0, 60.0, 135.0, 179.9})
    for (size_t n : {2u, 3u}) {
      const uwbloc::Pose2 truth(2.5, -1.2, deg * M_PI / 180.0);
      const auto fit =
          fitRigidBody(placed(truth, {three.begin(), three.begin() + static_cast<long>(n)}, 0.05));
      ASSERT_TRUE(fit.has_value()) << deg << " " << n;
      EXPECT_NEAR(fit->pose.x(), truth.x(), 1e-9) << deg;
      EXPECT_NEAR(fit->pose.y(), truth.y(), 1e-9) << deg;
      EXPECT_NEAR(uwbloc::wrapAngle(fit->pose.z() - truth.z()), 0.0, 1e-9) << deg;
      EXPECT_NEAR(fit->chi2, 0.0, 1e-12) << deg;
    }
}

// Two points at +-a on the body's x axis, each measured with std sigma: the position (at their
// midpoint) has variance sigma^2 / 2 on each axis and the heading sigma^2 / (2 a^2). Stretching
// the measured pair by d splits the stretch between them: chi2 = 2 (d / 2)^2 / sigma^2.
TEST(RigidFit, CovarianceAndChiSquareAreTheAnalyticOnes) {
  const double a = 0.2, sigma = 0.05, d = 0.04;
  const uwbloc::Pose2 truth(1.0, 2.0, 0.7);
  auto points = placed(truth, {{-a, 0.0}, {a, 0.0}}, sigma);
  auto fit = fitRigidBody(points);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->covariance(0, 0), sigma * sigma / 2.0, 1e-12);
  EXPECT_NEAR(fit->covariance(1, 1), sigma * sigma / 2.0, 1e-12);
  EXPECT_NEAR(fit->covariance(2, 2), sigma * sigma / (2.0 * a * a), 1e-12);
  EXPECT_NEAR(fit->covariance(0, 2), 0.0, 1e-12);
  const Eigen::Vector2d along(std::cos(truth.z()), std::sin(truth.z()));
  points[0].measured -= 0.5 * d * along;
  points[1].measured += 0.5 * d * along;
  fit = fitRigidBody(points);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->chi2, 2.0 * (d / 2.0) * (d / 2.0) / (sigma * sigma), 1e-9);
  EXPECT_NEAR(fit->point_chi2[0], fit->point_chi2[1], 1e-9);
  EXPECT_NEAR((fit->pose - truth).norm(), 0.0, 1e-9);
}

// A point measured less surely pulls the fit less: with full covariances, the fit weighs each
// point by its own (here one point is 10x less sure along one axis, and is off along it).
TEST(RigidFit, WeighsEachPointByItsCovariance) {
  const uwbloc::Pose2 truth(0.0, 0.0, 0.0);
  auto points = placed(truth, {{-0.2, 0.0}, {0.2, 0.0}, {0.0, 0.3}}, 0.02);
  points[2].covariance(0, 0) = 0.2 * 0.2;
  points[2].measured.x() += 0.1;
  const auto fit = fitRigidBody(points);
  ASSERT_TRUE(fit.has_value());
  EXPECT_LT(std::abs(fit->pose.x()), 0.01);
  EXPECT_GT(fit->point_chi2[2], 0.0);
}

TEST(RigidFit, RefusesWhatCannotGiveAHeading) {
  EXPECT_FALSE(fitRigidBody(placed({0, 0, 0}, {{0.1, 0.1}}, 0.05)).has_value());
  EXPECT_FALSE(fitRigidBody(placed({0, 0, 0}, {{0.1, 0.1}, {0.1, 0.1}}, 0.05)).has_value());
  auto bad = placed({0, 0, 0}, {{-0.1, 0.0}, {0.1, 0.0}}, 0.05);
  bad[0].covariance << 1.0, 2.0, 2.0, 1.0;  // not positive definite
  EXPECT_FALSE(fitRigidBody(bad).has_value());
  bad[0].covariance = Eigen::Matrix2d::Identity() * std::nan("");
  EXPECT_FALSE(fitRigidBody(bad).has_value());
}
