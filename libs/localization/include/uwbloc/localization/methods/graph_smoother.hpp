// Batch smoothing of a whole run over a Ceres range + odometry graph, produced at the end of the
// stream. Anchors fixed or self-calibrated, optional per-anchor range bias, robust loss for NLOS.
//  - graph-uwb-odom: one pose vertex per odometry increment, initialised by dead reckoning from
//    the start pose; each range attached to the vertex nearest in time.
//  - pf-ibas+graph (the PF-IBAS paper's full method, §2.2): the front-end filter runs online;
//    each of its estimates becomes a pose vertex with a prior (its mean and covariance), linked
//    to the previous one by the odometry between them; the ranges constrain the vertices, and so
//    do LiDAR corner landmarks (extracted from each scan, associated by nearest neighbour with a
//    Mahalanobis gate from the front end's poses, kept when seen `landmark_min_obs` times).
#pragma once

#include <array>
#include <deque>
#include <memory>

#include "uwbloc/localization/graph/range_graph.hpp"
#include "uwbloc/localization/lidar/landmarks.hpp"
#include "uwbloc/localization/range_front_end.hpp"
#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc {

/// What links consecutive pose vertices: the odometry (a vertex per increment), or, for the
/// ranges alone, a constant-velocity prior (a vertex per range time, white acceleration of
/// spectral density q).
enum class GraphMotion { kOdometry, kConstantVelocity };
constexpr std::array<EnumName<GraphMotion>, 2> enumNames(GraphMotion) {
  return {{{GraphMotion::kOdometry, "odom"}, {GraphMotion::kConstantVelocity, "cv"}}};
}

struct GraphSmootherParams {
  RangeFrontEndParams front;  ///< range checks; sigma is the range edges' std
  graph::RobustLoss loss = graph::RobustLoss::kCauchy;  ///< on ranges
  double loss_scale = 2.0;                              ///< in standard deviations
  double odom_sigma_xy = 0.01;                          ///< per increment [m] ...
  double odom_sigma_xy_per_m = 0.05;                    ///< ... plus this per metre moved
  double odom_sigma_theta = 0.005;                      ///< per increment [rad] ...
  double odom_sigma_theta_per_rad = 0.05;               ///< ... plus this per radian turned
  /// A factor on the odometry model's std; auto: learnt by leave-one-anchor-out
  /// cross-validation (crossValidatedOdometryFactor)
  AutoDouble odom_noise;
  GraphMotion motion = GraphMotion::kOdometry;          ///< what links the pose vertices
  AutoDouble accel_psd;  ///< motion=cv: q [m^2/s^3]; auto: estimated with the range std
  BiasMode bias = BiasMode::kAuto;                      ///< a range bias per anchor
  /// bias=auto with sigma=auto: also try the biases free (a bias on one anchor among few, which
  /// the path hides from the offsets)
  bool bias_trial = true;
  bool bias_trial_common = false;    ///< the trial frees one bias shared by every anchor
  /// motion=odom: the trial's biases per anchor stand only when the ranges alone (graph-uwb
  /// over the same ranges) take biases too; with bias_trial_common, tried after the common bias
  bool bias_trial_confirm = false;
  BiasMode scale = BiasMode::kAuto;  ///< a range scale common to the anchors: z = (1 + s) d + b
  int noise_rounds = 8;  ///< sigma=auto: at most this many variance re-estimates and re-solves
  /// sigma=auto: the range edges take the NLOS mixture learnt from the residuals, when one is
  bool nlos_mixture = true;
  /// Under the mixture: each range's NLOS fraction from its link's other ranges nearby in time
  /// (nlosStatePriors), when that predicts the residuals better than one fraction for all
  bool nlos_state = true;
  bool estimate_anchors = false;  ///< anchors' x, y with a prior
  double anchor_prior = 0.5;      ///< [m]
  int iterations = 100;
  std::string front_end;          ///< "" or a method spec whose estimates become vertices
  bool landmarks = true;          ///< front-end mode: LiDAR corner landmarks as vertices
  double landmark_sigma = 0.05;   ///< std of a corner observation [m]
  int landmark_min_obs = 3;       ///< landmarks seen fewer times are left out
  bool icp = false;               ///< front-end mode: add ICP relative-pose edges (lidar-icp)
  double icp_sigma_xy = 0.03;     ///< ICP edge std [m]
  double icp_sigma_theta = 0.01;  ///< ICP edge std [rad]
  bool covariance = false;        ///< batch: fill each pose's covariance (marginals.hpp)
  bool lagged = true;             ///< window mode: report each vertex once N-2 later ones are in
  int window = 0;                 ///< 0: batch; N: fixed-lag window of N front-end vertices
  double prior_min_xy = 0.02;     ///< floor on a front-end prior's std [m]
  double prior_min_theta = 0.01;  ///< floor on a front-end prior's heading std [rad]

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("loss", loss, "robust loss on ranges: none, huber or cauchy");
    v("loss_scale", loss_scale, "robust-loss scale [std]");
    v("odom_xy", odom_sigma_xy, "odometry edge std per increment [m]");
    v("odom_xy_per_m", odom_sigma_xy_per_m, "odometry edge std per metre moved");
    v("odom_th", odom_sigma_theta, "odometry edge heading std per increment [rad]");
    v("odom_th_per_rad", odom_sigma_theta_per_rad, "odometry edge heading std per radian turned");
    v("odom_noise", odom_noise,
      "a factor on the odometry edges' std (the four odom_* above), or auto: motion=odom without "
      "a front end learns it by cross-validation (each anchor's ranges predicted by the path "
      "solved without them; the model is halved, down to 1/64, while that prediction improves "
      "beyond chance)");
    v("motion", motion,
      "what links the pose vertices: odom (a vertex per odometry increment) or cv (ranges "
      "alone: a vertex per range time, a constant-velocity prior between them)");
    v("q", accel_psd,
      "motion=cv: white-acceleration spectral density [m^2/s^3], or auto (estimated from the "
      "data with the range std)");
    v("bias", bias,
      "a range bias per anchor: 0, 1 or auto (when an anchor's median residual exceeds its "
      "residual spread)");
    v("bias_trial", bias_trial,
      "bias=auto with sigma=auto: when no offset stands out, also solve with the biases free and "
      "keep them when they explain a quarter of the range variance (a bias on one anchor among "
      "few, which the path hides from the offsets)");
    v("bias_trial_common", bias_trial_common,
      "the bias trial frees one bias common to every anchor instead of one per anchor (an "
      "anchor whose error drifts over the learning span cannot pass for it)");
    v("bias_trial_confirm", bias_trial_confirm,
      "motion=odom: the trial's biases per anchor stand only when a smoother of the ranges "
      "alone (graph-uwb over the same ranges) takes biases as well (an error of the odometry "
      "over the span cannot pass for them); with bias_trial_common, tried when the common bias "
      "does not stand");
    v("scale", scale,
      "a range scale common to every anchor (z = (1 + s) d + bias): 0, 1 or auto (when the "
      "residuals grow with the distance, alike in both halves of the run)");
    v("noise_rounds", noise_rounds,
      "sigma=auto: variance-component re-estimates of the range std (each a re-solve)");
    v("nlos_mixture", nlos_mixture,
      "sigma=auto: when the range residuals are better explained by a LOS Gaussian plus an "
      "exponential NLOS excess (fitRangeMixture's BIC test), the range edges take that "
      "mixture's likelihood instead of the robust loss, learnt again from each solve's "
      "residuals (at most 3 rounds)");
    v("nlos_state", nlos_state,
      "under the NLOS mixture: each range's NLOS fraction is its link's (anchor and tag) over "
      "its other ranges nearby in time (an anchor out of sight for a while), the time constant "
      "chosen among 1/16 to 256 s by the residuals' leave-one-out likelihood; kept only when "
      "that beats one fraction for every range");
    v("anchors", estimate_anchors, "self-calibrate the anchors (x, y)");
    v("anchor_prior", anchor_prior, "anchor prior std [m]");
    v("iterations", iterations, "solver iterations");
    v("front", front_end, "front-end method whose estimates become the vertices (empty: odometry)");
    v("landmarks", landmarks, "front-end mode: LiDAR corner landmarks as vertices");
    v("landmark_sigma", landmark_sigma, "std of a corner observation [m]");
    v("landmark_min_obs", landmark_min_obs, "leave out landmarks seen fewer times");
    v("icp", icp, "front-end mode: add relative-pose edges from scan matching (lidar-icp)");
    v("icp_xy", icp_sigma_xy, "ICP edge std [m]");
    v("icp_th", icp_sigma_theta, "ICP edge std [rad]");
    v("covariance", covariance, "batch: compute each output pose's covariance (slower)");
    v("lagged", lagged,
      "window mode: output each pose with a lag of N-2 vertices (else the newest)");
    v("window", window, "0: batch over the whole run; N: online fixed-lag window of N vertices");
    v("prior_min_xy", prior_min_xy, "floor on a front-end prior's std [m]");
    v("prior_min_theta", prior_min_theta, "floor on a front-end prior's heading std [rad]");
  }
};

class GraphSmoother : public UwbEstimator {
 public:
  GraphSmoother(const GraphSmootherParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::vector<PoseEstimate> doFinishAll() override;

 private:
  /// Adds the front end's counts to this method's, its rejections as "front:<reason>", and its
  /// range decisions (so the report scores the front end's NLOS test under this method's name).
  void mergeFrontStatistics();
  std::vector<PoseEstimate> finishWindow();
  Eigen::Vector3d odometrySigma(const Eigen::Vector3d& increment) const;
  std::vector<double> addPoseVertices(graph::RangeGraph& g) const;
  void addIcpEdges(graph::RangeGraph& g, const std::vector<double>& times) const;
  void addLandmarks(graph::RangeGraph& g, const std::vector<double>& times) const;
  void addRanges(graph::RangeGraph& g, const std::vector<double>& times);
  /// nlos_state: the priors for the graph's ranges under `m`, from their `residuals` (anchor
  /// id and residual, in the order added, the biases taken out as the mixture's fit had them);
  /// nothing when the state does not predict them better than m's w.
  std::optional<NlosStatePriors> nlosStatePriors(
      const graph::RangeGraph& g, const RangeMixture& m,
      const std::vector<std::pair<int, double>>& residuals) const;

  GraphSmootherParams params_;
  EstimatorContext context_;
  std::unique_ptr<Estimator> front_;
  std::unique_ptr<Estimator> icp_;
  std::vector<PoseEstimate> icp_poses_;
  std::vector<double> range_times_;  ///< each range edge's time, in the order addRanges added
  // Collected along the run; the graph is built at the end.
  std::vector<OdometryIncrement> odometry_;
  std::vector<AcceptedRange> ranges_;
  std::vector<PoseEstimate> front_estimates_;
  struct ScanCorners {
    double t;
    std::vector<Eigen::Vector2d> corners;  ///< robot frame
  };
  std::vector<ScanCorners> corners_;
  // Sliding window state.
  struct WindowVertex {
    PoseEstimate front;
    Eigen::Vector3d pose;             ///< latest solution
    Eigen::Vector3d odometry_before;  ///< increment from the previous vertex
    std::vector<AcceptedRange> ranges;
  };
  std::vector<WindowVertex> window_;
  double last_output_t_ = -1e300;
  std::deque<OdometryIncrement> odometry_pending_;  ///< not yet before a window vertex
  std::deque<AcceptedRange> ranges_pending_;        ///< not yet on a window vertex
  std::optional<PoseEstimate> addWindowVertex(const PoseEstimate& e);
  std::optional<PoseEstimate> solveWindow();
  /// Sliding-window mode (needs a front end); otherwise everything is kept for one batch solve.
  bool online() const { return front_ && params_.window > 0; }
  graph::RangeGraphParams graphParams() const;
  /// Solves the batch graph: with sigma=auto, the range std by variance-component estimation
  /// first (no bias), then the biases when `bias` says so, then the odometry model's factor
  /// (odom_noise=auto; the range std stays); fills the estimated noise.
  void solveBatch(graph::RangeGraph& g);
  /// odom_noise=auto: leave-one-anchor-out cross-validation of the odometry model's scale. For
  /// a factor f on the odometry edges' std, each anchor's ranges are left out in turn, the graph
  /// is solved from the current solution without them, and their residuals about their own
  /// median are scored by the robust loss (at the residuals' pooled spread about each anchor's
  /// median, or under the NLOS mixture at its LOS std with each range's loss weighed by its LOS
  /// probability; the biases and the scale held). Starting at the factor in `p`, f is halved
  /// (down to 1/64) while the held-out ranges' mean loss falls and the solves succeed; a factor
  /// is taken when its losses beat those of the factor taken before beyond chance (a paired
  /// test over blocks of consecutive ranges). Returns the last factor that passed (the one in
  /// `p` when fewer than two anchors have ranges to hold out); the graph is left at the solution
  /// it started from.
  double crossValidatedOdometryFactor(graph::RangeGraph& g, const graph::RangeGraphParams& p);
  /// bias=auto, with a bias per anchor solved in `g` under `p`: whether one bias shared by
  /// every anchor explains the ranges as well, by the Bayesian information criterion on the two
  /// solves' costs at the range std learnt from the per-anchor solution: the shared bias stands
  /// when twice its cost's rise is below (anchors with ranges - 1) ln(ranges). When it stands,
  /// `p` takes it and `g` holds its solution; otherwise both are as they were. Graphs beyond
  /// kMaxPosesForNoiseEstimate keep their biases unjudged.
  bool preferCommonBias(graph::RangeGraph& g, graph::RangeGraphParams& p);
  /// Solves; counts an unusable solution and returns false.
  bool solveOnce(graph::RangeGraph& g, const graph::RangeGraphParams& p);
  Eigen::Vector3d priorSigma(const PoseEstimate& e) const;
  /// motion=cv: a vertex per range time (ranges within 1 ms share one), at the per-epoch
  /// multilateration fixes interpolated in time, linked by constant-velocity edges.
  std::vector<double> addRangeVertices(graph::RangeGraph& g) const;
  /// motion=cv: the poses out, at the tag's smoothed track, heading along its motion.
  std::vector<PoseEstimate> trackPoses(const graph::RangeGraph& g,
                                       const std::vector<double>& times) const;
  bool constantVelocity() const { return params_.motion == GraphMotion::kConstantVelocity; }
  /// bias_trial_confirm: whether graph-uwb (the ranges alone, constant-velocity prior, its own
  /// bias trial) takes biases on this smoother's ranges of the primary tag.
  bool rangesAloneTakeBiases() const;
  double first_t_ = 0.0;
  bool started_ = false;
};

}  // namespace uwbloc::loc
