#include "uwbloc/localization/motion_models.hpp"

#include <cmath>

#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::loc {

void constantVelocityModel(double dt, double q, Eigen::Matrix4d& f, Eigen::Matrix4d& qd,
                           double tau) {
  f.setIdentity();
  f(0, 2) = f(1, 3) = dt;
  if (tau > 0.0) {
    const double decay = std::exp(-dt / tau);
    f(0, 2) = f(1, 3) = tau * (1.0 - decay);
    f(2, 2) = f(3, 3) = decay;
  }
  const double dt2 = dt * dt, dt3 = dt2 * dt;
  qd.setZero();
  qd(0, 0) = qd(1, 1) = q * dt3 / 3.0;
  qd(0, 2) = qd(2, 0) = qd(1, 3) = qd(3, 1) = q * dt2 / 2.0;
  qd(2, 2) = qd(3, 3) = q * dt;
}

double HeadingFromMotion::update(const Eigen::Vector2d& velocity) {
  if (velocity.norm() >= min_speed_) {
    heading_ = std::atan2(velocity.y(), velocity.x());
    valid_ = true;
  }
  return heading_;
}

Eigen::Vector2d robotFromTag(const Eigen::Vector2d& tag, const Eigen::Vector3d& tag_on_robot,
                             double heading) {
  return tag - rotation(heading) * tag_on_robot.head<2>();
}

}  // namespace uwbloc::loc
