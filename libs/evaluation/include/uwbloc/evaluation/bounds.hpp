// Cramér–Rao bounds for UWB positioning along a known (true) trajectory.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"

namespace uwbloc::eval {

/// Static CRLB of the planar position of a tag at known height `tag_z` ranging to `anchors` with
/// noise `sigma`: (sum_i u_i u_i^T / sigma^2)^-1, u_i = (p - a_i)_xy / ||(p, tag_z) - a_i||,
/// the derivative of each 3D range with respect to (x, y). Nothing when singular.
std::optional<Eigen::Matrix2d> staticCrlb(const std::vector<uwb::Anchor>& anchors,
                                          const Eigen::Vector2d& p, double tag_z, double sigma);

/// Static CRLB of a robot's planar position from one epoch of ranges of each of its tags (their
/// places on the robot, `tags`) to `anchors`, its heading unknown too: the position block of
/// J^-1, J = sum over tags and anchors of h^T h / sigma^2 with h = d range / d(x, y, theta) at
/// `pose`. When no range depends on the heading (every lever arm zero), J's position block alone.
/// Nothing when singular.
std::optional<Eigen::Matrix2d> staticCrlbOfPose(const std::vector<uwb::Anchor>& anchors,
                                                const Eigen::Vector3d& pose,
                                                const std::vector<Eigen::Vector3d>& tags,
                                                double sigma);

struct BoundSeries {
  std::vector<double> t;
  std::vector<double> position_variance;  ///< trace of the 2x2 position block of the bound [m^2]
  /// Mean position variance after `burn_in` seconds (the prior's influence has faded then).
  double mean(double burn_in = 0.0) const;
};

/// Static CRLB at every ground-truth sample, all anchors in view: of the tag's position with one
/// tag on the robot (staticCrlb), of the robot's position with several (staticCrlbOfPose).
BoundSeries staticCrlbSeries(const data::Dataset& dataset, double sigma);

/// Posterior CRLB (Tichavský's recursion) for tracking along the true trajectory, with the
/// dataset's ranges (times and anchors of the robot's own tag) as measurements:
///   J_{k+1} = (Q_k + F_k J_k^-1 F_k^T)^-1 + H^T H / sigma^2.
/// motion "cv": state [x y vx vy], constant velocity with white acceleration `accel_psd`;
/// motion "odometry": state [x y theta] driven by the dataset's odometry increments with the
/// given noise model (H then includes the lever arm's dependence on theta).
/// The prior is 1 m (and 1 m/s or 1 rad) standard deviation.
BoundSeries posteriorCrlb(const data::Dataset& dataset, const data::BoundsSpec& spec);

}  // namespace uwbloc::eval
