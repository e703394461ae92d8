// The planar pose of the project, and the SE(2) maths every library shares. Eigen only.
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace uwbloc {

/// A planar pose (x, y, theta) [m, m, rad]: the robot in the map frame, a sensor on the robot,
/// or an increment in the frame of the pose it starts from.
using Pose2 = Eigen::Vector3d;

/// Wraps an angle to (-pi, pi].
inline double wrapAngle(double a) {
  a = std::fmod(a + M_PI, 2.0 * M_PI);
  if (a <= 0.0) a += 2.0 * M_PI;
  return a - M_PI;
}

/// R(theta), the rotation of a planar pose.
inline Eigen::Matrix2d rotation(double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

/// dR/dtheta.
inline Eigen::Matrix2d rotationDerivative(double theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  Eigen::Matrix2d r;
  r << -s, -c, c, -s;
  return r;
}

/// T(pose) p = t + R(theta) p: a point given in the pose's frame, in the outer frame.
inline Eigen::Vector2d transformPoint(const Pose2& pose, const Eigen::Vector2d& p) {
  const double c = std::cos(pose.z()), s = std::sin(pose.z());
  return {pose.x() + c * p.x() - s * p.y(), pose.y() + s * p.x() + c * p.y()};
}

/// T(pose)^-1 p = R(theta)^T (p - t): a point of the outer frame, in the pose's frame.
inline Eigen::Vector2d inverseTransformPoint(const Pose2& pose, const Eigen::Vector2d& p) {
  const double c = std::cos(pose.z()), s = std::sin(pose.z());
  const Eigen::Vector2d d = p - pose.head<2>();
  return {c * d.x() + s * d.y(), -s * d.x() + c * d.y()};
}

/// pose ⊕ delta: composes a pose with an increment expressed in its own frame.
inline Pose2 composePose(const Pose2& pose, const Pose2& delta) {
  const Eigen::Vector2d p = transformPoint(pose, delta.head<2>());
  return {p.x(), p.y(), wrapAngle(pose.z() + delta.z())};
}

/// from ⊖ to: the increment that takes `from` to `to`, in the frame of `from`.
inline Pose2 relativePose(const Pose2& from, const Pose2& to) {
  const Eigen::Vector2d p = inverseTransformPoint(from, to.head<2>());
  return {p.x(), p.y(), wrapAngle(to.z() - from.z())};
}

}  // namespace uwbloc
