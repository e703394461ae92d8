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

Eigen::Matrix<double, 5, 1> ctrvPredict(const Eigen::Matrix<double, 5, 1>& s, double dt,
                                        Eigen::Matrix<double, 5, 5>* f,
                                        Eigen::Matrix<double, 5, 5>* q, double sigma_a,
                                        double sigma_yaw) {
  const double v = s(2), th = s(3), w = s(4);
  const double th1 = th + w * dt;
  Eigen::Matrix<double, 5, 1> out = s;
  if (f) f->setIdentity();
  if (std::abs(w) > 1e-6) {
    out(0) += v / w * (std::sin(th1) - std::sin(th));
    out(1) += v / w * (std::cos(th) - std::cos(th1));
    if (f) {
      (*f)(0, 2) = (std::sin(th1) - std::sin(th)) / w;
      (*f)(0, 3) = v / w * (std::cos(th1) - std::cos(th));
      (*f)(0, 4) = v * dt / w * std::cos(th1) - v / (w * w) * (std::sin(th1) - std::sin(th));
      (*f)(1, 2) = (std::cos(th) - std::cos(th1)) / w;
      (*f)(1, 3) = v / w * (std::sin(th1) - std::sin(th));
      (*f)(1, 4) = v * dt / w * std::sin(th1) - v / (w * w) * (std::cos(th) - std::cos(th1));
    }
  } else {
    // The limit omega -> 0 (its Jacobian in omega: the first-order term of the expansion).
    out(0) += v * dt * std::cos(th);
    out(1) += v * dt * std::sin(th);
    if (f) {
      (*f)(0, 2) = dt * std::cos(th);
      (*f)(0, 3) = -v * dt * std::sin(th);
      (*f)(0, 4) = -0.5 * v * dt * dt * std::sin(th);
      (*f)(1, 2) = dt * std::sin(th);
      (*f)(1, 3) = v * dt * std::cos(th);
      (*f)(1, 4) = 0.5 * v * dt * dt * std::cos(th);
    }
  }
  out(3) = th1;
  if (f) (*f)(3, 4) = dt;
  if (q) {
    Eigen::Matrix<double, 5, 2> g = Eigen::Matrix<double, 5, 2>::Zero();
    g(0, 0) = 0.5 * dt * dt * std::cos(th);
    g(1, 0) = 0.5 * dt * dt * std::sin(th);
    g(2, 0) = dt;
    g(3, 1) = 0.5 * dt * dt;
    g(4, 1) = dt;
    *q = g * Eigen::Vector2d(sigma_a * sigma_a, sigma_yaw * sigma_yaw).asDiagonal() * g.transpose();
  }
  return out;
}

double HeadingFromMotion::update(const Eigen::Vector2d& velocity) {
  if (velocity.norm() >= min_speed_) {
    heading_ = std::atan2(velocity.y(), velocity.x());
    valid_ = true;
  }
  return heading_;
}

Eigen::Vector2d tagFromRobot(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot) {
  return pose.head<2>() + rotation(pose.z()) * tag_on_robot.head<2>();
}

Eigen::Vector2d robotFromTag(const Eigen::Vector2d& tag, const Eigen::Vector3d& tag_on_robot,
                             double heading) {
  return tag - rotation(heading) * tag_on_robot.head<2>();
}

}  // namespace uwbloc::loc
