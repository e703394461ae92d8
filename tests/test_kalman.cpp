// The shared Kalman steps against hand-computed values: innovation, gate, Joseph update,
// constant-velocity predict, the start from a fix and the UWB-only pose.
#include <gtest/gtest.h>

#include <cmath>

#include "uwbloc/localization/kalman/cubature.hpp"
#include "uwbloc/localization/kalman/kalman.hpp"
#include "uwbloc/localization/kalman/sage_husa.hpp"
#include "uwbloc/localization/motion_models.hpp"

using namespace uwbloc;
using namespace uwbloc::loc::kalman;

TEST(Kalman, OneUpdateByHand) {
  // State [x v], P = diag(4, 1), x measured (H = [1 0], R = 1), z = 2 from x = 0:
  // S = 5, d^2 = 4/5, K = [4/5 0], x = [1.6 0], P = diag(0.8, 1) (Joseph: 0.16 + 0.64).
  Vec<2> x(0.0, 0.0);
  Mat<2, 2> p = Eigen::Vector2d(4.0, 1.0).asDiagonal();
  const Mat<1, 2> h(1.0, 0.0);
  const Mat<1, 1> r(1.0);
  const auto inn = innovate<2, 1>(p, Vec<1>(2.0), h, r);
  EXPECT_NEAR(inn.s(0, 0), 5.0, 1e-12);
  EXPECT_NEAR(inn.d2, 0.8, 1e-12);
  EXPECT_FALSE(inGate(inn, uwb::ChiSquareGate(0.5)));
  EXPECT_TRUE(inGate(inn, uwb::ChiSquareGate(1.0)));
  josephUpdate<2, 1>(x, p, inn, h, r);
  EXPECT_NEAR(x(0), 1.6, 1e-12);
  EXPECT_NEAR(x(1), 0.0, 1e-12);
  EXPECT_NEAR(p(0, 0), 0.8, 1e-12);
  EXPECT_NEAR(p(1, 1), 1.0, 1e-12);
  EXPECT_NEAR(p(0, 1), 0.0, 1e-12);
}

TEST(Kalman, JosephUpdateWithCorrelatedState) {
  // P = [[2 1] [1 2]], H = [1 0], R = 1, y = 1: S = 3, K = [2/3 1/3],
  // x = [2/3 1/3], P = P - K S K^T = [[2/3 1/3] [1/3 5/3]].
  Vec<2> x = Vec<2>::Zero();
  Mat<2, 2> p;
  p << 2, 1, 1, 2;
  const Mat<1, 2> h(1.0, 0.0);
  const Mat<1, 1> r(1.0);
  josephUpdate<2, 1>(x, p, innovate<2, 1>(p, Vec<1>(1.0), h, r), h, r);
  EXPECT_NEAR(x(0), 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(x(1), 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(p(0, 0), 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(p(0, 1), 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(p(1, 1), 5.0 / 3.0, 1e-12);
}

TEST(Kalman, ConstantVelocityPredictByHand) {
  // dt = 2, q = 0.3, no velocity decay: x = [1 2 0.5 -1] -> [2 0 0.5 -1];
  // P = I -> F F^T + Q with F F^T = [[1+4 .. 2] ...] and Q = q [[8/3 2] [2 2]] per axis.
  Vec<4> x(1.0, 2.0, 0.5, -1.0);
  Mat<4, 4> p = Mat<4, 4>::Identity();
  predictConstantVelocity(x, p, 2.0, 0.3, 0.0);
  EXPECT_NEAR(x(0), 2.0, 1e-12);
  EXPECT_NEAR(x(1), 0.0, 1e-12);
  EXPECT_NEAR(p(0, 0), 5.0 + 0.3 * 8.0 / 3.0, 1e-12);
  EXPECT_NEAR(p(0, 2), 2.0 + 0.3 * 2.0, 1e-12);
  EXPECT_NEAR(p(2, 2), 1.0 + 0.3 * 2.0, 1e-12);
  EXPECT_NEAR(p(0, 1), 0.0, 1e-12);
}

TEST(Kalman, StartFromAFixAndTheTagTrackPose) {
  uwb::Fix fix;
  fix.status = uwb::FixStatus::kOk;
  fix.position = Eigen::Vector2d(3.0, 4.0);
  fix.covariance << 0.04, 0.01, 0.01, 0.09;
  Vec<4> x;
  Mat<4, 4> p;
  initialiseFromFix(fix, x, p, 1.0);
  EXPECT_EQ(x, Vec<4>(3.0, 4.0, 0.0, 0.0));
  EXPECT_NEAR(p(0, 1), 0.01, 1e-15);
  EXPECT_NEAR(p(2, 2), 1.0, 1e-15);
  EXPECT_NEAR(p(0, 2), 0.0, 1e-15);
  // Tag 0.2 m ahead of the robot, heading +90 deg: the robot is 0.2 m "behind" in -y.
  const auto est = tagTrackPose(7.0, fix.position, fix.covariance, {0.2, 0.0, 1.0}, M_PI / 2);
  EXPECT_NEAR(est.pose.x(), 3.0, 1e-12);
  EXPECT_NEAR(est.pose.y(), 3.8, 1e-12);
  EXPECT_FALSE(est.heading_valid);
  EXPECT_NEAR(est.covariance(2, 2), M_PI * M_PI, 1e-12);
  EXPECT_NEAR(est.covariance(1, 1), 0.09, 1e-15);
}

// One scalar state for the Sage-Husa cases: x = 0, P = 1, q̂ = 0, Q̂ = 0.5, r̂ = 0, R̂ = 1, k = 1.
struct ScalarCase {
  Vec<1> x = Vec<1>(0.0);
  Mat<1, 1> p = Mat<1, 1>(1.0);
  SageHusaProcess<1> process{Vec<1>(0.0), Mat<1, 1>(0.5), 1};
  SageHusaMeasurement<1> meas{Vec<1>(0.0), Mat<1, 1>(1.0), 1};
  SageHusaStep step(double z, double gamma, double r_floor) {
    return sageHusaStep<1, 1>(x, p, process, meas, Mat<1, 1>(1.0), Vec<1>(z), Mat<1, 1>(1.0), 0.5,
                              gamma, r_floor);
  }
};

// The Sage-Husa step (greenhouse eq. 15-16, 24) on one scalar state, by hand: F = H = 1,
// x = 0, P = 1, q̂ = 0, Q̂ = 0.5, r̂ = 0, R̂ = 1, z = 2, b = 0.5 at k = 1, so d = 0.5 / 0.75 = 2/3.
//   predict x = 0, P = 1.5; e = 2, S = 2.5, K = 0.6; x = 1.2, P = 0.4^2 1.5 + 0.6^2 = 0.6;
//   q̂ = 2/3 * 1.2 = 0.8;  Q̂ = 1/3 * 0.5 + 2/3 (0.36 * 4 + 0.6 - 1) = 0.86;
//   r̂ = 2/3 * 2 = 4/3;    R̂ = 1/3 + 2/3 (4 - 1.5) = 2.
TEST(SageHusa, OneAdaptiveStepByHand) {
  ScalarCase c;
  const auto step = c.step(2.0, 0.0, 0.01);
  EXPECT_NEAR(step.d, 2.0 / 3.0, 1e-12);
  EXPECT_FALSE(step.diverged);
  EXPECT_NEAR(c.x(0), 1.2, 1e-12);
  EXPECT_NEAR(c.p(0, 0), 0.6, 1e-12);
  EXPECT_NEAR(c.process.q(0), 0.8, 1e-12);
  EXPECT_NEAR(c.process.Q(0, 0), 0.86, 1e-12);
  EXPECT_NEAR(c.meas.r(0), 4.0 / 3.0, 1e-12);
  EXPECT_NEAR(c.meas.R(0, 0), 2.0, 1e-12);
  EXPECT_EQ(c.meas.k, 2);
  EXPECT_EQ(c.process.k, 2);
  EXPECT_NEAR(sageHusaWeight(0.5, 0), 1.0, 1e-12);  // d_0 = 1: the first step replaces
}

// The means held at zero (uwb-akf's default on the fix): the first step is the one above but
// for q̂ = r̂ = 0 (Q̂ = 0.86, R̂ = 2 as there). The second, z = 2 again: predict x = 1.2 (no q̂),
// P = 0.6 + 0.86 = 1.46; e = 0.8 (no r̂), S = 3.46, x = 1.2 + 0.8 * 1.46 / 3.46.
TEST(SageHusa, TheMeansCanBeHeldAtZero) {
  ScalarCase c;
  c.process.mean = false;
  c.meas.mean = false;
  c.step(2.0, 0.0, 0.01);
  EXPECT_NEAR(c.x(0), 1.2, 1e-12);
  EXPECT_EQ(c.process.q(0), 0.0);
  EXPECT_EQ(c.meas.r(0), 0.0);
  EXPECT_NEAR(c.process.Q(0, 0), 0.86, 1e-12);
  EXPECT_NEAR(c.meas.R(0, 0), 2.0, 1e-12);
  c.step(2.0, 0.0, 0.01);
  EXPECT_NEAR(c.x(0), 1.2 + 0.8 * 1.46 / 3.46, 1e-12);
}

// The same step with the IAKF's divergence test (gamma = 1): e'e = 4 > tr(S) = 2.5, so eq. (22)
// gives C = (4 - (0.5 + 1)) / 1 = 2.5 and eq. (21) P = 2.5 * 1 + 0.5 = 3; then S = 4, K = 0.75,
// x = 1.5, P = 0.25^2 3 + 0.75^2 = 0.75; q̂ = 1, Q̂ = 1/6 + 2/3 (0.5625 * 4 + 0.75 - 1) = 1.5,
// R̂ = 1/3 + 2/3 (4 - 3) = 1.
TEST(SageHusa, TheDivergenceTestInflatesThePrediction) {
  ScalarCase c;
  const auto step = c.step(2.0, 1.0, 0.01);
  EXPECT_TRUE(step.diverged);
  EXPECT_NEAR(step.inflation, 2.5, 1e-12);
  EXPECT_NEAR(c.x(0), 1.5, 1e-12);
  EXPECT_NEAR(c.p(0, 0), 0.75, 1e-12);
  EXPECT_NEAR(c.process.q(0), 1.0, 1e-12);
  EXPECT_NEAR(c.process.Q(0, 0), 1.5, 1e-12);
  EXPECT_NEAR(c.meas.R(0, 0), 1.0, 1e-12);
}

// The positivity guard: a measurement on the prediction (e = 0) makes the printed R update
// 1/3 + 2/3 (0 - 1.5) = -2/3; R̂ is kept at r_floor^2 and the projection is reported.
TEST(SageHusa, TheEstimatedRStaysPositiveDefinite) {
  ScalarCase c;
  const auto step = c.step(0.0, 0.0, 0.1);
  EXPECT_TRUE(step.r_projected);
  EXPECT_NEAR(c.meas.R(0, 0), 0.01, 1e-12);
}

// R̂ from the post-fit residual (from_residual), on the step of OneAdaptiveStepByHand: x = 1.2,
// P = 0.6 as there, the residual ε = e - H (x_k - x_{k/k-1}) = 2 - 1.2 = 0.8, so
// R̂ = 1/3 * 1 + 2/3 (0.8^2 + 0.6) = 1.16. On the prediction (z = 0) the innovation form goes
// negative (TheEstimatedRStaysPositiveDefinite); the residual form gives 1/3 + 2/3 * 0.6 = 11/15
// with nothing projected.
TEST(SageHusa, TheResidualFormOfRByHand) {
  ScalarCase c;
  c.meas.from_residual = true;
  const auto step = c.step(2.0, 0.0, 0.01);
  EXPECT_NEAR(c.x(0), 1.2, 1e-12);
  EXPECT_NEAR(c.p(0, 0), 0.6, 1e-12);
  EXPECT_NEAR(c.meas.r(0), 4.0 / 3.0, 1e-12);
  EXPECT_NEAR(c.meas.R(0, 0), 1.16, 1e-12);
  EXPECT_FALSE(step.r_projected);
  ScalarCase still;
  still.meas.from_residual = true;
  EXPECT_FALSE(still.step(0.0, 0.0, 0.1).r_projected);
  EXPECT_NEAR(still.meas.R(0, 0), 11.0 / 15.0, 1e-12);
}

// The CTRV model (mobile-node paper §2.3, standard form): one step by hand, and its Jacobian
// against central differences, turning and (the omega -> 0 branch) straight.
TEST(Ctrv, OneStepByHandAndTheJacobianAgainstNumbers) {
  using S = Eigen::Matrix<double, 5, 1>;
  // v = 1, theta = 0, omega = pi/2 over dt = 1: a quarter circle of radius 2/pi.
  const S turned = loc::ctrvPredict((S() << 0, 0, 1, 0, M_PI / 2).finished(), 1.0);
  EXPECT_NEAR(turned(0), 2.0 / M_PI, 1e-12);
  EXPECT_NEAR(turned(1), 2.0 / M_PI, 1e-12);
  EXPECT_NEAR(turned(3), M_PI / 2, 1e-12);
  const S straight = loc::ctrvPredict((S() << 1, 2, 2, M_PI / 2, 0).finished(), 0.5);
  EXPECT_NEAR(straight(0), 1.0, 1e-12);
  EXPECT_NEAR(straight(1), 3.0, 1e-12);
  for (const S& s0 :
       {(S() << 1, -2, 1.5, 0.7, 0.4).finished(), (S() << 1, -2, 1.5, 0.7, 0.0).finished()}) {
    Eigen::Matrix<double, 5, 5> f;
    loc::ctrvPredict(s0, 0.3, &f);
    for (int j = 0; j < 5; ++j) {
      // At omega = 0 the model switches branch below |omega| = 1e-6: differences step past it.
      const double eps = (j == 4 && s0(4) == 0.0) ? 1e-4 : 1e-6;
      S up = s0, down = s0;
      up(j) += eps;
      down(j) -= eps;
      const S numeric = (loc::ctrvPredict(up, 0.3) - loc::ctrvPredict(down, 0.3)) / (2 * eps);
      const double tol = 1e-7;
      for (int i = 0; i < 5; ++i) EXPECT_NEAR(f(i, j), numeric(i), tol) << i << "," << j;
    }
  }
  // The process noise: G diag(sa^2, sy^2) G^T, e.g. Q(2,2) = dt^2 sa^2, Q(4,4) = dt^2 sy^2.
  Eigen::Matrix<double, 5, 5> f, q;
  loc::ctrvPredict((S() << 0, 0, 1, 0, 0).finished(), 2.0, &f, &q, 0.5, 0.2);
  EXPECT_NEAR(q(2, 2), 4.0 * 0.25, 1e-12);
  EXPECT_NEAR(q(4, 4), 4.0 * 0.04, 1e-12);
  EXPECT_NEAR(q(0, 2), 2.0 * 2.0 * 0.25, 1e-12);  // dt^2/2 * dt * sa^2
  EXPECT_NEAR(q(1, 1), 0.0, 1e-12);
}

// ---- The point-based filters (kalman/cubature.hpp) ----

// The cubature rule on h(x) = x^2 with x ~ N(m, s^2): the two points m ± s give the exact mean
// m^2 + s^2 and the variance 4 m^2 s^2 (the third-degree rule misses the true variance's
// 2 s^4), and the cross-covariance 2 m s^2.
TEST(Cubature, MomentsOfASquareByHand) {
  const double m = 3.0, s = 0.5;
  const Vec<1> x(m);
  const Mat<1, 1> p(s * s);
  const auto set = cubaturePoints<1>(x, p);
  EXPECT_NEAR(set.x(0, 0), m + s, 1e-12);
  EXPECT_NEAR(set.x(0, 1), m - s, 1e-12);
  const auto mo = propagate<1, 1>(set, x, [](const Vec<1>& v) { return Vec<1>(v(0) * v(0)); });
  EXPECT_NEAR(mo.z(0), m * m + s * s, 1e-12);
  EXPECT_NEAR(mo.pzz(0, 0), 4 * m * m * s * s, 1e-12);
  EXPECT_NEAR(mo.pxz(0, 0), 2 * m * s * s, 1e-12);
}

// A linear measurement through the cubature update is the Kalman update exactly; the same
// numbers as Kalman.JosephUpdateWithCorrelatedState.
TEST(Cubature, LinearUpdateIsTheKalmanUpdate) {
  Vec<2> x = Vec<2>::Zero();
  Mat<2, 2> p;
  p << 2, 1, 1, 2;
  const auto mo = propagate<2, 1>(cubaturePoints<2>(x, p), x,
                                  [](const Vec<2>& v) { return Vec<1>(v(0)); });
  cubatureUpdate<2, 1>(x, p, mo, Vec<1>(1.0), Mat<1, 1>(1.0));
  EXPECT_NEAR(x(0), 2.0 / 3, 1e-12);
  EXPECT_NEAR(x(1), 1.0 / 3, 1e-12);
  EXPECT_NEAR(p(0, 0), 2.0 / 3, 1e-12);
  EXPECT_NEAR(p(0, 1), 1.0 / 3, 1e-12);
  EXPECT_NEAR(p(1, 1), 5.0 / 3, 1e-12);
  // The time update through a linear f is F P F^T + Q.
  Mat<2, 2> f;
  f << 1, 0.5, 0, 1;
  const Mat<2, 2> q = Eigen::Vector2d(0.1, 0.2).asDiagonal();
  const Mat<2, 2> expected = f * p * f.transpose() + q;
  const Vec<2> x_expected = f * x;
  cubaturePredict<2>(x, p, [&](const Vec<2>& v) { return Vec<2>(f * v); }, q);
  EXPECT_TRUE(x.isApprox(x_expected, 1e-12));
  EXPECT_TRUE(p.isApprox(expected, 1e-12));
}

// The H∞ update in one dimension: P = 1, H = 1, R = 1, y = 1. The CKF posterior is 1/2; with
// γ = 2 sqrt(1/2), γ^-2 = 1/2 and P = (1 + 1 - 1/2)^-1 = 2/3; the state is the CKF's, 1/2.
// As the ratio grows the covariance tends to the CKF's.
TEST(Cubature, HinfUpdateByHand) {
  auto run = [](double ratio, double* gamma) {
    Vec<1> x(0.0);
    Mat<1, 1> p(1.0);
    const auto mo =
        propagate<1, 1>(cubaturePoints<1>(x, p), x, [](const Vec<1>& v) { return v; });
    *gamma = hinfCubatureUpdate<1, 1>(x, p, mo, Vec<1>(1.0), Mat<1, 1>(1.0), ratio,
                                      Mat<1, 1>::Identity());
    EXPECT_NEAR(x(0), 0.5, 1e-12);
    return p(0, 0);
  };
  double gamma = 0.0;
  EXPECT_NEAR(run(2.0, &gamma), 2.0 / 3, 1e-12);
  EXPECT_NEAR(gamma, 2.0 * std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(run(1e4, &gamma), 0.5, 1e-6);
  // A selection L that excludes the measured state leaves the CKF's covariance.
  Vec<2> x = Vec<2>::Zero();
  Mat<2, 2> p = Mat<2, 2>::Identity();
  const auto mo = propagate<2, 1>(cubaturePoints<2>(x, p), x,
                                  [](const Vec<2>& v) { return Vec<1>(v(0)); });
  const Mat<2, 2> only_second = Eigen::Vector2d(0, 1).asDiagonal();
  hinfCubatureUpdate<2, 1>(x, p, mo, Vec<1>(1.0), Mat<1, 1>(1.0), 2.0, only_second);
  EXPECT_NEAR(p(0, 0), 0.5, 1e-12);
  EXPECT_NEAR(p(1, 1), 1.0 / (1.0 - 1.0 / (4.0 * 1.0)), 1e-12);  // γ^2 = 4 λ_max(L P L) = 4
}

// Rank-one Cholesky update and downdate against L L^T ± u u^T; a downdate that would make the
// matrix indefinite is refused, and the rebuild floors it.
TEST(Cubature, CholeskyRankOneUpdateAndDowndate) {
  Mat<3, 3> a;
  a << 4, 1, 0.5, 1, 3, 0.2, 0.5, 0.2, 2;
  Mat<3, 3> l = lowerSquareRoot<3>(a);
  const Vec<3> u(0.3, -0.5, 0.7);
  ASSERT_TRUE(choleskyRankOne<3>(l, u, 1.0));
  EXPECT_TRUE((l * l.transpose()).isApprox(a + u * u.transpose(), 1e-12));
  ASSERT_TRUE(choleskyRankOne<3>(l, u, -1.0));
  EXPECT_TRUE((l * l.transpose()).isApprox(a, 1e-12));
  EXPECT_TRUE(l.isLowerTriangular(1e-12));
  const Vec<3> big(3.0, 0.0, 0.0);
  const Mat<3, 3> before = l;
  EXPECT_FALSE(choleskyRankOne<3>(l, big, -1.0));
  EXPECT_TRUE(l.isApprox(before));
  EXPECT_FALSE(choleskyRankOneOrRebuild<3>(l, big, -1.0));
  EXPECT_TRUE(l.allFinite());
  EXPECT_GE((l * l.transpose()).eigenvalues().real().minCoeff(), -1e-9);
}

// The square-root unscented filter on a linear model is the Kalman filter, for the default
// points (alpha 1, beta 2, kappa 0) and for a negative zeroth weight (kappa = -1: lambda = -1,
// wc_0 = -1/3 + 2), whose rank-one update is a downdate.
TEST(Cubature, SquareRootUnscentedOnALinearModelIsTheKalmanFilter) {
  for (const double kappa : {0.0, -1.0}) {
    Vec<2> x(1.0, -0.5);
    Mat<2, 2> p;
    p << 2, 0.3, 0.3, 1;
    Mat<2, 2> s = lowerSquareRoot<2>(p);
    Mat<2, 2> f;
    f << 1, 0.1, 0, 1;
    const Mat<2, 2> q = Eigen::Vector2d(0.01, 0.04).asDiagonal();
    sqrtUnscentedPredict<2>(x, s, [&](const Vec<2>& v) { return Vec<2>(f * v); },
                            lowerSquareRoot<2>(q), 1.0, 2.0, kappa);
    Vec<2> xk = f * Vec<2>(1.0, -0.5);
    Mat<2, 2> pk = f * p * f.transpose() + q;
    EXPECT_TRUE(x.isApprox(xk, 1e-12)) << kappa;
    EXPECT_TRUE((s * s.transpose()).isApprox(pk, 1e-12)) << kappa;
    // Measure the first state: z = 1.4, R = 0.25.
    const auto set = unscentedPoints<2>(x, s, 1.0, 2.0, kappa);
    const auto mo = propagate<2, 1>(set, x, [](const Vec<2>& v) { return Vec<1>(v(0)); });
    sqrtUnscentedUpdate<2, 1>(x, s, set, mo, Vec<1>(1.4 - mo.z(0)), Mat<1, 1>(0.5));
    const Mat<1, 2> h(1.0, 0.0);
    const auto inn = innovate<2, 1>(pk, Vec<1>(1.4 - xk(0)), h, Mat<1, 1>(0.25));
    josephUpdate<2, 1>(xk, pk, inn, h, Mat<1, 1>(0.25));
    EXPECT_TRUE(x.isApprox(xk, 1e-12)) << kappa;
    EXPECT_TRUE((s * s.transpose()).isApprox(pk, 1e-12)) << kappa;
  }
}
