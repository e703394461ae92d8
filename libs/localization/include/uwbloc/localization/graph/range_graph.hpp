// Graph back end on Ceres: robot poses (x, y, theta) with an angle manifold, UWB anchors
// (fixed, or estimated with a prior) and an optional per-anchor range bias as vertices; UWB range
// edges (PF-IBAS paper eq. 29) with a robust loss, and relative-pose edges from odometry. Every
// residual is whitened by its standard deviation. Build and solve are separate.
#pragma once

#include <Eigen/Core>
#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "uwbloc/localization/params.hpp"
#include "uwbloc/localization/range_mixture.hpp"
#include "uwbloc/uwb/types.hpp"

namespace ceres {
class Problem;
}

namespace uwbloc::loc::graph {

/// Robust loss on the whitened range residuals.
enum class RobustLoss { kNone, kHuber, kCauchy };
constexpr std::array<EnumName<RobustLoss>, 3> enumNames(RobustLoss) {
  return {{{RobustLoss::kNone, "none"},
           {RobustLoss::kHuber, "huber"},
           {RobustLoss::kCauchy, "cauchy"}}};
}

struct RangeGraphParams {
  double range_sigma = 0.1;                          ///< std of a range [m]
  RobustLoss loss = RobustLoss::kCauchy;             ///< on the whitened range residuals
  double loss_scale = 2.0;                           ///< robust-loss scale, in standard deviations
  /// When set, the range edges take this mixture's likelihood (MixtureResidual: its LOS std
  /// widened by each range's variance scale) instead of range_sigma and the robust loss
  std::optional<RangeMixture> range_mixture;
  Eigen::Vector3d odometry_sigma{0.05, 0.05, 0.02};  ///< per odometry edge [m, m, rad]
  /// Multiplies the std of every odometry edge (its own or odometry_sigma)
  double odometry_sigma_factor = 1.0;
  /// Cross-validation: the ranges to the anchor of this index are left out of the problem
  /// (-1: none); rangeResiduals() still gives theirs
  int left_out_anchor = -1;
  bool estimate_anchors = false;    ///< anchors' x, y as vertices with a prior (z is held)
  double anchor_prior_sigma = 0.5;  ///< [m]
  bool estimate_bias = false;       ///< a range bias per anchor
  bool common_bias = false;         ///< with estimate_bias: one bias shared by every anchor
  double bias_prior_sigma = 5.0;    ///< [m]
  bool estimate_scale = false;      ///< a range scale common to every anchor: z = (1 + s) d + b
  double scale_prior_sigma = 0.1;   ///< prior std of s about 0 (a 10 % error is far beyond any)
  /// q of the constant-velocity edges: white-acceleration spectral density [m^2/s^3]
  double accel_psd = 1.0;
  int max_iterations = 100;
  int threads = 0;  ///< Ceres threads; 0: every core of the machine
};

/// The slope of the range residuals (z - (1 + s) d - b) against the distance d within anchors
/// (each anchor's residuals and distances centred on their own means, so that no bias adds to
/// it), pooled over the anchors: over all the ranges [0], and over each half of them in the
/// order added, i.e. in time [1], [2]. What is left of a scale error. Ranges beyond 3 robust
/// stds of the residuals are left out.
struct ScaleEvidence {
  double slope[3] = {0.0, 0.0, 0.0};      ///< least-squares slope [m/m]
  double slope_std[3] = {0.0, 0.0, 0.0};  ///< its standard error
  long ranges[3] = {0, 0, 0};             ///< ranges used
  double explained[3] = {0.0, 0.0, 0.0};  ///< share of the residuals' variance the slope explains
};

/// Residual statistics of one anchor's range edges after a solve.
struct AnchorResiduals {
  int anchor_id = 0;
  long ranges = 0;
  double bias = 0.0;    ///< the solved bias (0 when not estimated) [m]
  double median = 0.0;  ///< median of z - predicted distance (bias not subtracted) [m]
  double median_first_half = 0.0, median_second_half = 0.0;  ///< the same per half, in time [m]
  double robust_sigma = 0.0;  ///< 1.4826 MAD of z - predicted - bias [m]
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
  RangeGraph();
  ~RangeGraph();
  RangeGraph(RangeGraph&&) noexcept;
  RangeGraph& operator=(RangeGraph&&) noexcept;
  int addPose(const Eigen::Vector3d& initial);
  void setAnchors(const std::vector<uwb::Anchor>& anchors);
  /// A relative-pose edge; `sigma` (x, y, theta) replaces the parameters' odometry_sigma.
  void addOdometry(int from, int to, const Eigen::Vector3d& delta,
                   const std::optional<Eigen::Vector3d>& sigma = std::nullopt);
  /// A relative-pose edge with a full 3x3 information matrix (x, y, theta), as g2o and TORO
  /// files store it; throws std::invalid_argument when it is not positive definite.
  void addRelativePose(int from, int to, const Eigen::Vector3d& delta,
                       const Eigen::Matrix3d& information);
  /// `tag_id`: the tag the range came from (tagSigmas groups by it).
  void addRange(int pose, int anchor_id, double range, const Eigen::Vector3d& tag,
                double variance_scale = 1.0, int tag_id = 0);
  /// A constant-velocity edge through poses a, b, c, dt1 and dt2 [s] apart (positive): the
  /// motion prior of a graph without odometry (q: the parameters' accel_psd).
  void addConstantVelocity(int a, int b, int c, double dt1, double dt2);
  /// A landmark vertex (x, y), and an observation of it from a pose (robot frame, std sigma).
  int addLandmark(const Eigen::Vector2d& initial);
  void addLandmarkObservation(int pose, int landmark, const Eigen::Vector2d& z, double sigma);
  Eigen::Vector2d landmark(size_t i) const { return landmarks_[i]; }
  /// Marginal covariance of one pose after solve(), by ceres::Covariance (the reference the
  /// selected inversion is tested against); nothing if it fails.
  std::optional<Eigen::Matrix3d> poseCovariance(int pose);
  /// Marginal covariances of every pose after solve(), by selected inversion (marginals.hpp):
  /// zero for held poses; empty when it fails.
  std::vector<Eigen::Matrix3d> poseCovariances();
  /// A prior on a pose (e.g. the front-end filter's estimate), std per component.
  void addPosePrior(int pose, const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma);

  /// Creates the Ceres problem. Gauge: with fixed anchors the frame is fixed by them; when
  /// anchors are estimated, the first anchor and the first pose are held constant (see build()).
  void build(const RangeGraphParams& params);
  GraphSolution solve();
  /// After solve(): the range std re-estimated from the range edges' variance component
  /// (Helmert's estimator with the robust loss's weights): their weighted squared residuals over
  /// their redundancy, the part of them the solution did not absorb (sum of w - leverage, the
  /// leverage from the poses' marginal covariances), divided by the loss's consistency factor
  /// E[w z^2] / E[w] for Gaussian z (0.746 for the Cauchy loss at 2 std) so that Gaussian noise
  /// gives its own std. Nothing when the covariances cannot be computed or the ranges have no
  /// redundancy.
  std::optional<double> estimateRangeSigma();
  /// After solve(): the range std (as estimateRangeSigma) and the constant-velocity edges'
  /// q, each from its own group's variance component. q's redundancy is its edges' residual
  /// count less their leverage, and their leverage is what the other groups leave of the
  /// parameters (the leverages sum to the free parameters' count), so it needs no covariance
  /// between poses: the graph may hold ranges, constant-velocity edges, pose priors, biases and
  /// a scale, but no odometry, landmarks or free anchors (q is then nothing).
  /// On a simulated tag under white acceleration both settle at the truth
  /// (RangeSlam.ConstantVelocityGraphLearnsRangeNoiseAndMotionQ). A real path's q is that of
  /// the white acceleration that explains it best, not its mean squared acceleration.
  struct VarianceComponents {
    std::optional<double> range_sigma;  ///< [m]
    std::optional<double> accel_psd;    ///< [m^2/s^3]
  };
  VarianceComponents estimateVarianceComponents();
  /// After solve(): each range's anchor id and residual before its anchor's bias,
  /// z - (1 + scale) d [m], in the order added.
  std::vector<std::pair<int, double>> rangeResiduals() const;
  /// The same less each range's bias (its anchor's, or the common one): z - (1 + scale) d - b.
  std::vector<std::pair<int, double>> rangeResidualsLessBias() const;
  /// After solve(): each anchor's range residual statistics (ranges in the order added).
  std::vector<AnchorResiduals> anchorResiduals() const;
  /// After solve(): per tag id, its ranges' count and the robust std (1.4826 MAD) of their
  /// residuals z - predicted - bias about their median [m].
  std::map<int, std::pair<long, double>> tagSigmas() const;
  /// After solve(): the residuals' slope against distance (see ScaleEvidence).
  ScaleEvidence scaleEvidence() const;
  /// The values of every vertex (poses, anchors, biases, scale, landmarks), to go back to after
  /// a trial solve.
  struct Values {
    std::vector<Eigen::Vector3d> poses;
    std::vector<uwb::Anchor> anchors;
    std::vector<double> biases;
    double scale = 0.0;
    std::vector<Eigen::Vector2d> landmarks;
  };
  Values values() const { return {poses_, anchors_, biases_, scale_, landmarks_}; }
  /// Sets the vertices back (the same graph: sizes must match).
  void restore(const Values& v);
  /// Holds a pose constant (after build()): e.g. the oldest vertex of a sliding window.
  void holdPose(int pose);
  /// Under the parameters' range mixture: each range's NLOS fraction in place of the mixture's
  /// (nlosStatePriors), in the order added, taken at the next build() to the nearest 0.05 (one
  /// residual shape per level); empty: the mixture's for every range. Throws
  /// std::invalid_argument when neither empty nor one per range.
  void setNlosPriors(std::vector<double> priors);
  /// Each range's anchor id, tag id and variance scale (over range_sigma^2), in the order added.
  struct RangeEdge {
    int anchor_id, tag_id;
    double variance_scale;
  };
  std::vector<RangeEdge> rangeEdges() const;
  /// Holds the range biases and the scale at their values (after build()).
  void holdRangeModel();

  size_t poses() const { return poses_.size(); }
  size_t ranges() const { return ranges_.size(); }
  Eigen::Vector3d pose(size_t i) const { return poses_[i]; }
  const std::vector<uwb::Anchor>& anchors() const { return anchors_; }
  double bias(size_t anchor_index) const {
    return biases_[biasIndex(static_cast<int>(anchor_index))];
  }
  double scale() const { return scale_; }

 private:
  /// The bias an anchor's ranges take: its own, or the first (common_bias).
  size_t biasIndex(int anchor) const {
    return params_.common_bias ? 0 : static_cast<size_t>(anchor);
  }
  struct Range {
    int pose, anchor;
    double range;
    Eigen::Vector3d tag;
    double variance_scale;  ///< over range_sigma^2 (an NLOS model's doubt)
    int tag_id;
  };
  struct Odometry {
    int from, to;
    Eigen::Vector3d delta;
    std::optional<Eigen::Matrix3d> sqrt_information;  ///< upper triangular; none: the params'
  };
  std::vector<double> nlos_prior_;  ///< setNlosPriors
  std::vector<Eigen::Vector3d> poses_;
  std::vector<uwb::Anchor> anchors_;
  std::vector<Eigen::Vector3d> anchor_prior_;
  std::vector<double> biases_;
  double scale_ = 0.0;  ///< z = (1 + scale_) d + bias
  std::vector<Range> ranges_;
  std::vector<Odometry> odometry_;
  struct ConstantVelocity {
    int a, b, c;
    double dt1, dt2;
  };
  std::vector<ConstantVelocity> constant_velocity_;
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
  /// z - (1 + scale) distance(pose, anchor) - bias of one range edge, and its gradient in the
  /// pose; `distance` receives the distance.
  double rangeResidual(const Range& r, Eigen::Vector3d* gradient, double* distance = nullptr) const;
  /// Appends the free (not held) poses' parameter blocks to `blocks`; returns their indices.
  std::vector<size_t> freePoses(std::vector<double*>& blocks);
  /// The robust loss's weight rho'(s^2) at a whitened residual s.
  double lossWeight(double whitened) const;
  /// E[w z^2] / E[w] under a standard normal: the robust weights' shrinkage of a variance.
  double lossConsistency() const;
};

}  // namespace uwbloc::loc::graph
