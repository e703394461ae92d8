#include "uwbloc/localization/kalman/kalman.hpp"

#include <cmath>

#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc::kalman {

void predictConstantVelocity(Vec<4>& x, Mat<4, 4>& p, double dt, double accel_psd,
                             double velocity_tau) {
  Eigen::Matrix4d f, q;
  constantVelocityModel(dt, accel_psd, f, q, velocity_tau);
  x = f * x;
  p = f * p * f.transpose() + q;
}

void initialiseFromFix(const uwb::Fix& fix, Vec<4>& x, Mat<4, 4>& p, double velocity_sigma) {
  x << fix.position, 0.0, 0.0;
  p.setZero();
  p.topLeftCorner<2, 2>() = fix.covariance;
  p(2, 2) = p(3, 3) = velocity_sigma * velocity_sigma;
}

PoseEstimate tagTrackPose(double t, const Eigen::Vector2d& tag, const Eigen::Matrix2d& tag_cov,
                          const Eigen::Vector3d& tag_on_robot, double heading) {
  PoseEstimate est;
  est.t = t;
  est.pose << robotFromTag(tag, tag_on_robot, heading), heading;
  est.covariance.setZero();
  est.covariance.topLeftCorner<2, 2>() = tag_cov;
  est.covariance(2, 2) = M_PI * M_PI;
  est.heading_valid = false;
  return est;
}

namespace {
// [theta omega] over dt under white angular acceleration of density q.
void predictHeading(Vec<2>& x, Mat<2, 2>& p, double dt, double q) {
  Mat<2, 2> f;
  f << 1.0, dt, 0.0, 1.0;
  Mat<2, 2> qm;
  qm << q * dt * dt * dt / 3.0, q * dt * dt / 2.0, q * dt * dt / 2.0, q * dt;
  x = f * x;
  x(0) = wrapAngle(x(0));
  p = f * p * f.transpose() + qm;
}
}  // namespace

bool HeadingTrack::update(double t, double heading, double variance) {
  if (started_ && gated_in_a_row_ < max_gated_) {
    predictHeading(x_, p_, std::max(0.0, t - t_), accel_psd_);
    t_ = std::max(t_, t);
    const Mat<1, 2> h(1.0, 0.0);
    const Mat<1, 1> r = Mat<1, 1>::Constant(variance);
    const auto inn = innovate<2, 1>(p_, Vec<1>::Constant(wrapAngle(heading - x_(0))), h, r);
    if (!inGate(inn, uwb::ChiSquareGate(10.83))) {  // 1 dof, 99.9 %
      ++gated_in_a_row_;
      return false;
    }
    josephUpdate(x_, p_, inn, h, r);
    x_(0) = wrapAngle(x_(0));
    gated_in_a_row_ = 0;
    return true;
  }
  // The start: the measurement, and an angular rate of 1 rad/s std.
  x_ << wrapAngle(heading), 0.0;
  p_ << variance, 0.0, 0.0, 1.0;
  t_ = t;
  started_ = true;
  gated_in_a_row_ = 0;
  return true;
}

std::optional<std::pair<double, double>> HeadingTrack::at(double t) const {
  if (!started_) return std::nullopt;
  Vec<2> x = x_;
  Mat<2, 2> p = p_;
  predictHeading(x, p, std::max(0.0, t - t_), accel_psd_);
  return std::make_pair(x(0), p(0, 0));
}

}  // namespace uwbloc::loc::kalman
