#include "uwbloc/uwb/range_model.hpp"

#include <cmath>

#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::uwb {

std::optional<double> projectToPlane(double d, double dz) {
  // Eq. (3).
  const double r2 = d * d - dz * dz;
  if (!(r2 >= 0.0)) return std::nullopt;
  return std::sqrt(r2);
}

Eigen::Vector3d tagPosition(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot) {
  const Eigen::Vector2d xy = transformPoint(pose, tag_on_robot.head<2>());
  return {xy.x(), xy.y(), tag_on_robot.z()};
}

double predictRange(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot,
                    const Eigen::Vector3d& anchor, Eigen::RowVector3d* jacobian) {
  // h = || T(pose) * tag - anchor ||, the 3D distance with the lever arm rotated by theta.
  const Eigen::Vector3d tag = tagPosition(pose, tag_on_robot);
  const Eigen::Vector3d diff = tag - anchor;
  const double h = diff.norm();
  if (jacobian) {
    if (h < 1e-12) {
      jacobian->setZero();
    } else {
      // d(tag_xy)/d(theta) = R'(theta) lever = R(theta + pi/2) lever.
      const Eigen::Vector2d dt = rotation(pose.z() + M_PI_2) * tag_on_robot.head<2>();
      (*jacobian) << diff.x() / h, diff.y() / h, (diff.x() * dt.x() + diff.y() * dt.y()) / h;
    }
  }
  return h;
}

}  // namespace uwbloc::uwb
