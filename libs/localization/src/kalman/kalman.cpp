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

}  // namespace uwbloc::loc::kalman
