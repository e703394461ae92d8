// The planar pose of a rigid body from points measured on it: several tags on one robot, each
// multilaterated on its own, give the robot's position and heading.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::uwb {

/// One point of the body: where it sits in the body's frame, and where it was measured in the
/// outer frame, with that measurement's covariance.
struct BodyPoint {
  Eigen::Vector2d on_body = Eigen::Vector2d::Zero();
  Eigen::Vector2d measured = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
};

struct RigidFit {
  Pose2 pose = Pose2::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< (J^T W J)^-1 at the pose
  /// sum_k e_k^T C_k^-1 e_k, e_k = m_k - T b_k: chi-square with 2 n - 3 degrees of freedom when
  /// the covariances are right.
  double chi2 = 0.0;
  std::vector<double> point_chi2;  ///< each point's share of chi2
};

/// The pose T (x, y, theta) that takes the body points b_k onto their measurements m_k: the 2D
/// Procrustes solution with scalar weights w_k = 2 / tr C_k (closed form: theta from the weighted
/// cross and dot products about the weighted centroids) refined by Gauss-Newton on the full
/// covariances, min sum_k (m_k - t - R(theta) b_k)^T C_k^-1 (...). Nothing with fewer than two
/// points, points that coincide on the body (no heading) or a covariance that is not positive
/// definite.
std::optional<RigidFit> fitRigidBody(const std::vector<BodyPoint>& points);

/// The closed-form start alone: weighted 2D Procrustes. `weights` positive, one per point; at
/// least two points. Exposed for the multi-tag solver's start.
Pose2 procrustes2d(const std::vector<BodyPoint>& points, const std::vector<double>& weights);

}  // namespace uwbloc::uwb
