#include "uwbloc/uwb/range_model.hpp"

#include <cmath>

namespace uwbloc::uwb {

std::optional<double> projectToPlane(double d, double dz) {
  // Eq. (3).
  const double r2 = d * d - dz * dz;
  if (!(r2 >= 0.0)) return std::nullopt;
  return std::sqrt(r2);
}

Eigen::Vector3d tagPosition(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot) {
  const double c = std::cos(pose.z()), s = std::sin(pose.z());
  return {pose.x() + c * tag_on_robot.x() - s * tag_on_robot.y(),
          pose.y() + s * tag_on_robot.x() + c * tag_on_robot.y(), tag_on_robot.z()};
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
      const double c = std::cos(pose.z()), s = std::sin(pose.z());
      // d(tag_xy)/d(theta) = R'(theta) * lever
      const double dtx = -s * tag_on_robot.x() - c * tag_on_robot.y();
      const double dty = c * tag_on_robot.x() - s * tag_on_robot.y();
      (*jacobian) << diff.x() / h, diff.y() / h, (diff.x() * dtx + diff.y() * dty) / h;
    }
  }
  return h;
}

}  // namespace uwbloc::uwb
