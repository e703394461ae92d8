// The filtering toolkit every Kalman-family estimator shares: the constant-velocity predict, one
// Joseph-form update with numbered steps (after robot_localization's correct()), one Mahalanobis
// gate (uwb::ChiSquareGate), the start from a multilateration fix, and the UWB-only pose
// estimate. A filter's own code is then its own equations.
//
// The update, for a measurement z with prediction h(x), Jacobian H and noise R:
//   (1) innovation        y = z - h(x)
//   (2) its covariance    S = H P H^T + R
//   (3) Mahalanobis gate  d^2 = y^T S^-1 y <= threshold, else the update is skipped
//   (4) gain              K = P H^T S^-1
//   (5) state             x <- x + K y
//   (6) covariance        P <- (I - K H) P (I - K H)^T + K R K^T   (Joseph form: stays symmetric
//                         positive semi-definite for any K, unlike P <- (I - K H) P)
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>
#include <optional>
#include <utility>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/uwb/gates.hpp"
#include "uwbloc/uwb/multilateration.hpp"

namespace uwbloc::loc::kalman {

template <int N>
using Vec = Eigen::Matrix<double, N, 1>;
template <int R, int C>
using Mat = Eigen::Matrix<double, R, C>;

/// Steps (1)-(3) of one measurement: the innovation, its covariance and its squared
/// Mahalanobis distance.
template <int M>
struct Innovation {
  Vec<M> y;
  Mat<M, M> s;
  double d2 = 0.0;
};

/// Steps (1)-(2) and the distance of step (3). `y` is z - h(x), already formed by the caller
/// (angle components wrapped).
template <int N, int M>
Innovation<M> innovate(const Mat<N, N>& p, const Vec<M>& y, const Mat<M, N>& h,
                       const Mat<M, M>& r) {
  Innovation<M> out;
  out.y = y;                              // (1)
  out.s = h * p * h.transpose() + r;      // (2)
  out.d2 = y.dot(out.s.ldlt().solve(y));  // (3) y^T S^-1 y
  return out;
}

/// Step (3): accepts when d^2 <= the gate's threshold (chi-square with M degrees of freedom).
template <int M>
bool inGate(const Innovation<M>& inn, const uwb::ChiSquareGate& gate) {
  return gate.acceptSquared(inn.d2);
}

/// Steps (4)-(6): the Kalman gain, the state and the Joseph-form covariance update.
template <int N, int M>
void josephUpdate(Vec<N>& x, Mat<N, N>& p, const Innovation<M>& inn, const Mat<M, N>& h,
                  const Mat<M, M>& r) {
  const Mat<N, M> k = p * h.transpose() * inn.s.inverse();  // (4)
  x += k * inn.y;                                           // (5)
  const Mat<N, N> ikh = Mat<N, N>::Identity() - k * h;      // (6)
  p = ikh * p * ikh.transpose() + k * r * k.transpose();
}

/// Constant-velocity predict of [x y vx vy] over dt (motion_models.hpp):
///   x <- F x,  P <- F P F^T + Q.
void predictConstantVelocity(Vec<4>& x, Mat<4, 4>& p, double dt, double accel_psd,
                             double velocity_tau);

/// The state [x y vx vy] started from a multilateration fix: the fix's position and covariance,
/// zero velocity with `velocity_sigma` (1 m/s) of uncertainty.
void initialiseFromFix(const uwb::Fix& fix, Vec<4>& x, Mat<4, 4>& p, double velocity_sigma = 1.0);

/// The UWB-only pose estimate from a tag track: the robot's position is the tag's minus the lever
/// arm rotated by `heading` (which the track does not observe: heading_valid = false, variance
/// pi^2), the covariance the tag position's.
PoseEstimate tagTrackPose(double t, const Eigen::Vector2d& tag, const Eigen::Matrix2d& tag_cov,
                          const Eigen::Vector3d& tag_on_robot, double heading);

/// A heading measured directly, each epoch (several tags' rigid fits): the state [theta omega]
/// under white angular acceleration of density `accel_psd` [rad^2/s^3]. Each measurement is
/// gated (1 dof, 99.9 %); after `max_gated` refused in a row the track restarts on the next.
class HeadingTrack {
 public:
  explicit HeadingTrack(double accel_psd = 1.0, int max_gated = 5)
      : accel_psd_(accel_psd), max_gated_(max_gated) {}
  /// Predicts to t and updates with `heading` of variance `variance`; false when gated.
  bool update(double t, double heading, double variance);
  /// The heading and its variance predicted to t; nothing before the first measurement.
  std::optional<std::pair<double, double>> at(double t) const;
  void reset() { started_ = false; }

 private:
  double accel_psd_;
  int max_gated_;
  bool started_ = false;
  int gated_in_a_row_ = 0;
  double t_ = 0.0;
  Vec<2> x_ = Vec<2>::Zero();
  Mat<2, 2> p_ = Mat<2, 2>::Identity();
};

}  // namespace uwbloc::loc::kalman
