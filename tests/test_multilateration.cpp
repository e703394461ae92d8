// Multilateration: exact agreement without noise, efficiency against the Cramér-Rao bound,
// degenerate geometry, height projection and the range model's Jacobian.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "uwbloc/uwb/multilateration.hpp"
#include "uwbloc/uwb/range_model.hpp"

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
