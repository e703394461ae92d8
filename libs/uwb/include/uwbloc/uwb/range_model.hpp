// Geometry of one tag-to-anchor range.
#pragma once

#include <Eigen/Core>
#include <optional>

#include "uwbloc/uwb/types.hpp"

namespace uwbloc::uwb {

/// Height projection, the PF-IBAS paper's eq. (3): r = sqrt(d^2 - (z_a - z_t)^2).
/// Returns nothing when d < |dz|: the range is shorter than the height difference and cannot
/// be projected (the caller rejects and counts it).
std::optional<double> projectToPlane(double d, double dz);

/// Tag position in the map frame for a robot pose (x, y, theta) and the tag's offset on it.
Eigen::Vector3d tagPosition(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot);

/// Predicted 3D range from the robot pose to the anchor, with the tag lever arm.
/// If `jacobian` is given it receives d(range)/d(x, y, theta).
double predictRange(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot,
                    const Eigen::Vector3d& anchor, Eigen::RowVector3d* jacobian = nullptr);

}  // namespace uwbloc::uwb
