// Ceres cost functors of the range graph. Internal: consumers of the library see RangeGraph
// only, never a Ceres type. Each residual is whitened by its square-root information.
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <cmath>
#include <memory>
#include <utility>

#include "uwbloc/localization/range_mixture.hpp"

namespace uwbloc::loc::graph {

/// Plus(x, d) = (x + d_x, y + d_y, wrap(theta + d_theta)): the pose block's manifold.
struct PosePlus {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* out) const {
    out[0] = x[0] + delta[0];
    out[1] = x[1] + delta[1];
    T a = x[2] + delta[2];
    // Wrap to (-pi, pi] with operations autodiff can follow.
    out[2] = ceres::atan2(ceres::sin(a), ceres::cos(a));
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* delta) const {
    delta[0] = y[0] - x[0];
    delta[1] = y[1] - x[1];
    const T d = y[2] - x[2];
    delta[2] = ceres::atan2(ceres::sin(d), ceres::cos(d));
    return true;
  }
};

/// Eq. (29): e = (z - ||T(x) tag - a|| - b) / sigma, T(x) the robot pose applied to the tag's
/// lever arm, a the anchor, b the anchor's range bias. Parameters: pose[3], anchor[3], bias[1].
struct RangeCost {
  RangeCost(double range, const Eigen::Vector3d& tag, double sigma)
      : range_(range), tag_(tag), inv_sigma_(1.0 / sigma) {}
  /// The residual (z - (1 + scale) d - bias) / sigma: a range measures its distance d times
  /// 1 + scale (a clock or propagation-speed error common to the radios), plus the anchor's bias.
  template <typename T>
  bool operator()(const T* pose, const T* anchor, const T* bias, const T* scale,
                  T* residual) const {
    const T c = ceres::cos(pose[2]), s = ceres::sin(pose[2]);
    const T dx = pose[0] + c * tag_.x() - s * tag_.y() - anchor[0];
    const T dy = pose[1] + s * tag_.x() + c * tag_.y() - anchor[1];
    const T dz = T(tag_.z()) - anchor[2];
    residual[0] =
        (T(range_) - (T(1) + scale[0]) * ceres::sqrt(dx * dx + dy * dy + dz * dz) - bias[0]) *
        inv_sigma_;
    return true;
  }
  static ceres::CostFunction* Create(double range, const Eigen::Vector3d& tag, double sigma) {
    return new ceres::AutoDiffCostFunction<RangeCost, 1, 3, 3, 1, 1>(
        new RangeCost(range, tag, sigma));
  }
  const double range_;         ///< measured range [m]
  const Eigen::Vector3d tag_;  ///< tag on the robot (lever arm x, y; height z) [m]
  const double inv_sigma_;     ///< whitening: 1 / range std
};

/// A range under an NLOS mixture (RangeGraphParams::range_mixture): the residual
/// e = z - (1 + s) d - b of RangeCost (unwhitened) passed through the mixture's
/// MixtureResidual, its derivative carried by the chain rule. Parameters as RangeCost.
struct MixtureRangeCost {
  MixtureRangeCost(double range, const Eigen::Vector3d& tag,
                   std::shared_ptr<const MixtureResidual> shape)
      : range_(range, tag, 1.0), shape_(std::move(shape)) {}
  template <typename T>
  bool operator()(const T* pose, const T* anchor, const T* bias, const T* scale,
                  T* residual) const {
    T e;
    range_(pose, anchor, bias, scale, &e);
    residual[0] = apply(e);
    return true;
  }
  double apply(double e) const { return (*shape_)(e); }
  template <int N>
  ceres::Jet<double, N> apply(const ceres::Jet<double, N>& e) const {
    double slope = 0.0;
    const double f = (*shape_)(e.a, &slope);
    return ceres::Jet<double, N>(f, slope * e.v);
  }
  static ceres::CostFunction* Create(double range, const Eigen::Vector3d& tag,
                                     std::shared_ptr<const MixtureResidual> shape) {
    return new ceres::AutoDiffCostFunction<MixtureRangeCost, 1, 3, 3, 1, 1>(
        new MixtureRangeCost(range, tag, std::move(shape)));
  }
  const RangeCost range_;
  const std::shared_ptr<const MixtureResidual> shape_;
};

/// Relative pose between two poses against a measured increment (odometry or ICP):
///   r = L [R(a_theta)^T (b_xy - a_xy) - d_xy ; wrap(b_theta - a_theta - d_theta)],
/// L the upper-triangular square root of the edge's information (L^T L = Omega), so that
/// r^T r = e^T Omega e (the ceres pose_graph_2d form); a diagonal L whitens by each std.
struct RelativePoseCost {
  RelativePoseCost(const Eigen::Vector3d& delta, const Eigen::Matrix3d& sqrt_information)
      : delta_(delta), sqrt_information_(sqrt_information) {}
  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    const T c = ceres::cos(a[2]), s = ceres::sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T rx = c * dx + s * dy, ry = -s * dx + c * dy;  // b in a's frame
    const T dth = b[2] - a[2] - T(delta_.z());
    const T e[3] = {rx - T(delta_.x()), ry - T(delta_.y()),
                    ceres::atan2(ceres::sin(dth), ceres::cos(dth))};
    for (int i = 0; i < 3; ++i) {
      residual[i] = T(0);
      for (int j = 0; j < 3; ++j) residual[i] += T(sqrt_information_(i, j)) * e[j];
    }
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& delta,
                                     const Eigen::Matrix3d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<RelativePoseCost, 3, 3, 3>(
        new RelativePoseCost(delta, sqrt_information));
  }
  /// The same edge whitened per component by `sigma` (x, y, theta).
  static ceres::CostFunction* Create(const Eigen::Vector3d& delta, const Eigen::Vector3d& sigma) {
    return Create(delta, Eigen::Matrix3d(sigma.cwiseInverse().asDiagonal()));
  }
  const Eigen::Vector3d delta_;             ///< measured increment in a's frame
  const Eigen::Matrix3d sqrt_information_;  ///< upper-triangular L, L^T L = information
};

/// Constant velocity through three consecutive poses a, b, c (time steps dt1 = t_b - t_a,
/// dt2 = t_c - t_b) under white acceleration of spectral density q: the change of the mean
/// velocity, (c - b) / dt2 - (b - a) / dt1, is about N(0, q (dt1 + dt2) / 2) per axis (the
/// integral of the acceleration over the half steps around b). Positions only: the headings do
/// not enter. Parameters: a[3], b[3], c[3].
struct ConstantVelocityCost {
  ConstantVelocityCost(double dt1, double dt2, double accel_psd)
      : inv_dt1_(1.0 / dt1), inv_dt2_(1.0 / dt2),
        inv_sigma_(1.0 / std::sqrt(accel_psd * 0.5 * (dt1 + dt2))) {}
  template <typename T>
  bool operator()(const T* a, const T* b, const T* c, T* residual) const {
    for (int i = 0; i < 2; ++i)
      residual[i] = ((c[i] - b[i]) * inv_dt2_ - (b[i] - a[i]) * inv_dt1_) * inv_sigma_;
    return true;
  }
  static ceres::CostFunction* Create(double dt1, double dt2, double accel_psd) {
    return new ceres::AutoDiffCostFunction<ConstantVelocityCost, 2, 3, 3, 3>(
        new ConstantVelocityCost(dt1, dt2, accel_psd));
  }
  const double inv_dt1_, inv_dt2_;  ///< [1/s]
  const double inv_sigma_;          ///< whitening: 1 / std of the velocity change [s/m]
};

/// A prior on a parameter block: (x - x0) / sigma per component (anchor self-calibration,
/// range bias, or a pose from the front-end filter).
template <int N>
struct PriorCost {
  PriorCost(const Eigen::Matrix<double, N, 1>& x0, const Eigen::Matrix<double, N, 1>& sigma)
      : x0_(x0), inv_sigma_(sigma.cwiseInverse()) {}
  template <typename T>
  bool operator()(const T* x, T* residual) const {
    for (int i = 0; i < N; ++i) residual[i] = (x[i] - T(x0_(i))) * inv_sigma_(i);
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Matrix<double, N, 1>& x0,
                                     const Eigen::Matrix<double, N, 1>& sigma) {
    return new ceres::AutoDiffCostFunction<PriorCost, N, N>(new PriorCost(x0, sigma));
  }
  const Eigen::Matrix<double, N, 1> x0_, inv_sigma_;
};

/// A prior on a pose, with the heading error wrapped.
struct PosePriorCost {
  PosePriorCost(const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma)
      : mean_(mean), inv_sigma_(sigma.cwiseInverse()) {}
  template <typename T>
  bool operator()(const T* x, T* residual) const {
    residual[0] = (x[0] - T(mean_.x())) * inv_sigma_.x();
    residual[1] = (x[1] - T(mean_.y())) * inv_sigma_.y();
    const T d = x[2] - T(mean_.z());
    residual[2] = ceres::atan2(ceres::sin(d), ceres::cos(d)) * inv_sigma_.z();
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma) {
    return new ceres::AutoDiffCostFunction<PosePriorCost, 3, 3>(new PosePriorCost(mean, sigma));
  }
  const Eigen::Vector3d mean_, inv_sigma_;
};

/// LiDAR landmark observation, the PF-IBAS paper's eq. (5): the landmark m seen from pose x is
/// z = R(theta)^T (m - t); residual (z_meas - z) / sigma. Parameters: pose[3], landmark[2].
struct LandmarkCost {
  LandmarkCost(const Eigen::Vector2d& z, double sigma) : z_(z), inv_sigma_(1.0 / sigma) {}
  template <typename T>
  bool operator()(const T* pose, const T* landmark, T* residual) const {
    const T c = ceres::cos(pose[2]), s = ceres::sin(pose[2]);
    const T dx = landmark[0] - pose[0], dy = landmark[1] - pose[1];
    residual[0] = (T(z_.x()) - (c * dx + s * dy)) * inv_sigma_;
    residual[1] = (T(z_.y()) - (-s * dx + c * dy)) * inv_sigma_;
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector2d& z, double sigma) {
    return new ceres::AutoDiffCostFunction<LandmarkCost, 2, 3, 2>(new LandmarkCost(z, sigma));
  }
  const Eigen::Vector2d z_;  ///< observed landmark in the robot frame [m]
  const double inv_sigma_;   ///< whitening
};

}  // namespace uwbloc::loc::graph
