// Graph back end on Ceres: robot poses (x, y, theta) with an angle manifold, UWB anchors
// (fixed, or estimated with a prior) and an optional per-anchor range bias as vertices; UWB range
// edges (PF-IBAS paper eq. 29) with a robust loss, and relative-pose edges from odometry. Every
// residual is whitened by its standard deviation. Build and solve are separate.
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/uwb/types.hpp"

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
  template <typename T>
  bool operator()(const T* pose, const T* anchor, const T* bias, T* residual) const {
    const T c = ceres::cos(pose[2]), s = ceres::sin(pose[2]);
    const T dx = pose[0] + c * tag_.x() - s * tag_.y() - anchor[0];
    const T dy = pose[1] + s * tag_.x() + c * tag_.y() - anchor[1];
    const T dz = T(tag_.z()) - anchor[2];
    residual[0] = (T(range_) - ceres::sqrt(dx * dx + dy * dy + dz * dz) - bias[0]) * inv_sigma_;
    return true;
  }
  static ceres::CostFunction* Create(double range, const Eigen::Vector3d& tag, double sigma) {
    return new ceres::AutoDiffCostFunction<RangeCost, 1, 3, 3, 1>(new RangeCost(range, tag, sigma));
  }
  const double range_;         ///< measured range [m]
  const Eigen::Vector3d tag_;  ///< tag on the robot (lever arm x, y; height z) [m]
  const double inv_sigma_;     ///< whitening: 1 / range std
};

/// Relative pose between two poses against a measured increment (odometry or ICP), each
/// component whitened by its standard deviation; the angle error is wrapped.
struct RelativePoseCost {
  RelativePoseCost(const Eigen::Vector3d& delta, const Eigen::Vector3d& sigma)
      : delta_(delta), inv_sigma_(sigma.cwiseInverse()) {}
  template <typename T>
  bool operator()(const T* a, const T* b, T* residual) const {
    const T c = ceres::cos(a[2]), s = ceres::sin(a[2]);
    const T dx = b[0] - a[0], dy = b[1] - a[1];
    const T rx = c * dx + s * dy, ry = -s * dx + c * dy;  // b in a's frame
    const T dth = b[2] - a[2] - T(delta_.z());
    residual[0] = (rx - T(delta_.x())) * inv_sigma_.x();
    residual[1] = (ry - T(delta_.y())) * inv_sigma_.y();
    residual[2] = ceres::atan2(ceres::sin(dth), ceres::cos(dth)) * inv_sigma_.z();
    return true;
  }
  static ceres::CostFunction* Create(const Eigen::Vector3d& delta, const Eigen::Vector3d& sigma) {
    return new ceres::AutoDiffCostFunction<RelativePoseCost, 3, 3, 3>(
        new RelativePoseCost(delta, sigma));
  }
  const Eigen::Vector3d delta_;      ///< measured increment in a's frame
  const Eigen::Vector3d inv_sigma_;  ///< whitening per component
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

struct RangeGraphParams {
  double range_sigma = 0.1;     ///< std of a range [m]
  std::string loss = "cauchy";  ///< none, huber or cauchy (on whitened range residuals)
  double loss_scale = 2.0;      ///< robust-loss scale, in standard deviations
  Eigen::Vector3d odometry_sigma{0.05, 0.05, 0.02};  ///< per odometry edge [m, m, rad]
  bool estimate_anchors = false;    ///< anchors' x, y as vertices with a prior (z is held)
  double anchor_prior_sigma = 0.5;  ///< [m]
  bool estimate_bias = false;       ///< a range bias per anchor
  double bias_prior_sigma = 5.0;    ///< [m]
  int max_iterations = 100;
};

struct GraphSolution {
  bool usable = false;  ///< ceres' IsSolutionUsable()
  int iterations = 0;
  double initial_cost = 0.0, final_cost = 0.0;
  std::string report;  ///< ceres' brief report
};

/// A range + odometry graph. Add vertices and measurements, then build() and solve().
class RangeGraph {
 public:
  int addPose(const Eigen::Vector3d& initial);
  void setAnchors(const std::vector<uwb::Anchor>& anchors);
  /// A relative-pose edge; `sigma` (x, y, theta) replaces the parameters' odometry_sigma.
  void addOdometry(int from, int to, const Eigen::Vector3d& delta,
                   const std::optional<Eigen::Vector3d>& sigma = std::nullopt);
  void addRange(int pose, int anchor_id, double range, const Eigen::Vector3d& tag);
  /// A landmark vertex (x, y), and an observation of it from a pose (robot frame, std sigma).
  int addLandmark(const Eigen::Vector2d& initial);
  void addLandmarkObservation(int pose, int landmark, const Eigen::Vector2d& z, double sigma);
  Eigen::Vector2d landmark(size_t i) const { return landmarks_[i]; }
  /// Marginal covariance of a pose after solve() (ceres::Covariance); nothing if it fails.
  std::optional<Eigen::Matrix3d> poseCovariance(int pose);
  /// Marginal covariances of every pose in one ceres::Covariance computation (zero for held
  /// poses; empty when it fails).
  std::vector<Eigen::Matrix3d> poseCovariances();
  /// A prior on a pose (e.g. the front-end filter's estimate), std per component.
  void addPosePrior(int pose, const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma);

  /// Creates the Ceres problem. Gauge: with fixed anchors the frame is fixed by them; when
  /// anchors are estimated, the first anchor and the first pose are held constant (see build()).
  void build(const RangeGraphParams& params);
  GraphSolution solve();
  /// Holds a pose constant (after build()): e.g. the oldest vertex of a sliding window.
  void holdPose(int pose) {
    problem_->SetParameterBlockConstant(poses_[static_cast<size_t>(pose)].data());
  }

  size_t poses() const { return poses_.size(); }
  Eigen::Vector3d pose(size_t i) const { return poses_[i]; }
  const std::vector<uwb::Anchor>& anchors() const { return anchors_; }
  double bias(size_t anchor_index) const { return biases_[anchor_index]; }

 private:
  struct Range {
    int pose, anchor;
    double range;
    Eigen::Vector3d tag;
  };
  struct Odometry {
    int from, to;
    Eigen::Vector3d delta;
    std::optional<Eigen::Vector3d> sigma;
  };
  std::vector<Eigen::Vector3d> poses_;
  std::vector<uwb::Anchor> anchors_;
  std::vector<Eigen::Vector3d> anchor_prior_;
  std::vector<double> biases_;
  std::vector<Range> ranges_;
  std::vector<Odometry> odometry_;
  struct Prior {
    int pose;
    Eigen::Vector3d mean, sigma;
  };
  std::vector<Prior> priors_;
  std::vector<Eigen::Vector2d> landmarks_;
  struct LandmarkObs {
    int pose, landmark;
    Eigen::Vector2d z;
    double sigma;
  };
  std::vector<LandmarkObs> landmark_obs_;
  RangeGraphParams params_;
  std::unique_ptr<ceres::Problem> problem_;
};

}  // namespace uwbloc::loc::graph
