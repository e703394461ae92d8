// uwb-ekf: extended Kalman filter updating on each range directly (tightly coupled), with a
// constant-velocity state [x y vx vy] of the tag and a Mahalanobis innovation gate.
//
// Faulty anchors often report long runs of smoothly wrong ranges (the MRPT demo's beacon 1 is
// off by up to 10 m for tens of seconds), which an innovation gate alone lets back in as soon as
// the error shrinks below the gate. So an anchor whose range is gated is quarantined: its ranges
// are used again only after `readmit` consecutive ones pass the gate and lie within
// `readmit_tol` of the prediction. The second test matters where the other anchors leave a
// direction unobserved (on the line through two anchors): there the state's variance, and with
// it the gate, grows without bound, and a steady wrong range would otherwise be readmitted.
//
// An outage (no range for tens of seconds) lets the predicted position spread over metres. One
// range then constrains it to a ring, and the linearised, point-based or H∞ updates pick a point
// on the ring far from the robot. So when the predicted position's std exceeds `reinit_std`,
// the filter restarts from the next multilateration fix (event reinitialised_after_outage).
//
// The range model and q are learnt at the start (calib, default 60 s): the first seconds of
// ranges go to graph-uwb as well (LearningStart), and the filter then corrects every range by the
// learnt scale (and biases, with calib_bias), and widens sigma and raises q to what was learnt
// (never below their start values); see UwbEkfT::learn.
//
// On a robot with two tags or more (tags=auto), the filter and every range filter built on it
// (UwbEkfT<6>) estimates the robot's pose and its rates, [x y vx vy theta omega] (white
// acceleration with the velocity decay above, white angular acceleration yaw_accel_psd), updated
// by each range of every tag through its lever arm l_k:
//
//   r = || ((x, y) + R(theta) l_k_xy, z_k) - a ||,
//   dr/dtheta = (d_x (-s l_x - c l_y) + d_y (c l_x - s l_y)) / r,   d = tag - a.
//
// Two tags a known distance apart observe the heading from the ranges alone, so the heading is
// known while the robot stands still, which the one-tag filter (UwbEkfT<4>: the tag's position,
// the heading from the direction of motion) cannot know. The quarantine is then per anchor-tag
// link (a body blocks one tag's line of sight, not the anchor's). The start: the start pose
// (position std start_sigma, heading std start_sigma_yaw), or an epoch of ranges solved by
// uwb-multitag's Gauss-Newton (solveMultitag); the heading counts as observed (heading_valid)
// while its std is below kObservedHeadingStd.
#pragma once

#include <Eigen/Core>
#include <deque>
#include <map>
#include <memory>
#include <optional>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/kalman/cubature.hpp"
#include "uwbloc/localization/kalman/kalman.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"
#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc {

/// Where the filter starts: at the start pose (the manifest's, or the reference's first), or
/// from the first epoch that multilaterates. Re-initialisations after divergence always use a fix.
enum class EkfStart { kStartPose, kFix };
constexpr std::array<EnumName<EkfStart>, 2> enumNames(EkfStart) {
  return {{{EkfStart::kStartPose, "start"}, {EkfStart::kFix, "fix"}}};
}

struct UwbEkfParams {
  RangeFrontEndParams front;
  RobotTags tags = RobotTags::kAuto;
  EkfStart start = EkfStart::kStartPose;
  double start_sigma = 0.5;    ///< std of the start pose's position [m]
  AutoDouble epoch_window;     ///< epoch window of the initial fix [s]; auto: the data's rate
  AutoDouble q;                ///< white-acceleration spectral density [m^2/s^3]; auto: learnt
  double accel_psd = 0.1;      ///< the q in force: q's value, or the learnt one (not a key)
  RangeLearningParams learning;  ///< calib, calib_bias: the learning start (range_noise.hpp)
  double velocity_tau = 5.0;   ///< velocity correlation time [s]; 0 = constant velocity
  double gate = 9.0;           ///< chi-square gate on one range innovation (3 sigma, 1 dof)
  int max_gated = 12;          ///< consecutive unused ranges before re-initialising
  int readmit = 3;             ///< consecutive in-gate ranges before a quarantined anchor is used
  double readmit_tol = 1.0;    ///< and each within max(this, 3 sigma) of the prediction [m]
  double init_residual = 0.5;  ///< largest residual norm of an initial fix [m]
  double reinit_std = 3.0;     ///< predicted position std that restarts from a fix [m]; 0 = off
  double yaw_accel_psd = 1.0;  ///< two tags or more: white angular acceleration [rad^2/s^3]
  double start_sigma_yaw = 20.0;  ///< two tags or more: heading std at the start pose [deg]

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("tags", tags,
      "auto: every tag on the robot when it carries two or more (the pose and heading from the "
      "lever arms), else the primary tag; primary: the primary tag's ranges only");
    v("start", start, "start at the start pose (start) or at the first multilateration fix (fix)");
    v("start_sigma", start_sigma, "std of the start pose's position [m]");
    v("window", epoch_window, "epoch window of the initial fix [s], or auto");
    v("q", q,
      "white-acceleration spectral density [m^2/s^3]; auto: learnt at the start when calib > 0, "
      "else 0.1");
    learning.visit(v);
    v("tau", velocity_tau, "velocity correlation time [s]; 0 = constant velocity");
    v("gate", gate, "chi-square gate on each range innovation (1 dof)");
    v("max_gated", max_gated,
      "consecutive unused (gated or quarantined) ranges before re-initialising; also "
      "re-initialising when, over that many ranges, the filter used one anchor only and refused "
      "at least half of them, each beyond readmit_tol (event lost_on_one_anchor)");
    v("readmit", readmit, "in-gate ranges in a row before a gated anchor is used again");
    v("readmit_tol", readmit_tol, "largest |innovation| that counts towards readmission [m]");
    v("init_residual", init_residual, "largest residual norm of the initial fix [m]");
    v("reinit_std", reinit_std,
      "restart from a multilateration fix when an outage has grown the predicted position std "
      "beyond this [m]; 0 = never");
    v("yaw_accel_psd", yaw_accel_psd,
      "two tags or more: white angular acceleration density [rad^2/s^3]");
    v("start_sigma_yaw", start_sigma_yaw, "two tags or more: heading std at the start pose [deg]");
  }
};

/// The help of `fold_blind` in the point filters and federated-ekf (rangeFold).
inline constexpr const char* kFoldBlindHelp =
    "a range that folds over the state's spread (along one axis of the cubature points it is "
    "longer, or shorter, on both sides of the mean, each by more than the range's std: the tag "
    "near the line through two anchors, or the spread reaching past the anchor) is taken by the "
    "EKF's update: blind along that axis while the mean is within sqrt(gate) range stds of the "
    "fold (1, event blind_across_fold: the position crosses the fold on its velocity), and "
    "linearised at the mean once the range there exceeds the fold's least by more (event "
    "linearised_at_fold: the mean's side is then told by the range); or as it is (0: the "
    "points' moments average the fold's two sides and learn nothing across it; the slope at the "
    "mean throws the state across on a range a few centimetres short)";

/// A range's fold over a point set (rangeFold).
struct RangeFold {
  Eigen::Vector2d axis;  ///< the unit direction in the plane along which the range folds
  /// The range at the mean exceeds the least range along `axis` by more than the noise: the
  /// mean's side of the fold is known, and the linearisation at the mean holds.
  bool side_known = false;
  /// The event that counts the fold's update: linearised_at_fold or blind_across_fold.
  const char* event() const { return side_known ? "linearised_at_fold" : "blind_across_fold"; }
};

/// The direction in the plane along which the range of `r` folds over the symmetric points
/// `points` about the mean `x` (the cubature set, 2N points x +- c_i, or the unscented one, the
/// mean first), if it does: for some pair, the range at both points lies on the same side of the
/// range at the mean, each by more than `depth` (the deepest such pair's position offset).
/// Along it the range is not monotone across the spread (the tag near the line through two
/// anchors, moving along it; or the spread reaching past the anchor), and the points' moments
/// average its two sides: P_xz near zero, P_zz inflated by the curvature, the predicted range
/// biased long. The linearisation at the mean is no better near the fold: its slope along the
/// fold is the mean's small offset from the line, and a range a few centimetres short throws
/// the state across it. So with `fold_blind` the point filters and federated-ekf take such a
/// range by the EKF's update with the Jacobian's component along the fold removed
/// (UwbEkfT::linearCorrect), while the mean is near the fold. Near means that the range at the
/// mean, r, exceeds the least range along the axis, sqrt(r^2 - s^2) with s = (tag - anchor) .
/// axis, by at most `side_sigmas` times `depth` (the range's std): within the noise, the range
/// cannot tell the mean's side. Beyond, `side_known` is set and the filters take the EKF's full
/// update at the mean: the fold is then the spread's, not the mean's (the spread grows while a
/// range is blind across it, so the points fold ever more often: on the MRPT demo, blind on
/// every range, the cubature filter's spread along the fold reached 3.7 m within 9 s and, with
/// no restart, it was lost for good: 5.2 m RMSE).
template <int N, int K>
std::optional<RangeFold> rangeFold(const kalman::PointSet<N, K>& points, const kalman::Vec<N>& x,
                                   const AcceptedRange& r, double depth, double side_sigmas);

/// The quarantine of uwb-ekf and the filters built on it (see the top of this file): a link
/// whose range failed the gate is used again only after `readmit` in-gate ranges in a row, each
/// within `tolerance` of the prediction. A link is an anchor (one tag) or an anchor-tag pair.
class RangeQuarantine {
 public:
  using Link = std::pair<int, int>;  ///< (anchor id, tag id)
  /// True when the range may be used; a refused one is counted in `stats` against its anchor
  /// (innovation: failed the gate; quarantine: held back).
  bool admit(const Link& link, double innovation, bool in_gate, int readmit, double tolerance,
             EstimatorStatistics& stats);
  void clear() { held_.clear(); }

 private:
  std::map<Link, int> held_;  ///< link -> in-gate ranges seen since it was gated
};

/// uwb-ekf's learning (the learning start's statistics `learnt`): each range corrected by the
/// learnt scale (and biases with calib_bias) through `noise`, sigma widened and q raised to what
/// was learnt, never below their start values.
void learnRangeFilterNoise(const EstimatorStatistics& learnt, UwbEkfParams& params,
                           RangeNoiseModel& noise, EstimatorStatistics& stats);

/// The largest |innovation| that counts towards a quarantined link's readmission:
/// max(readmit_tol, 3 sigma).
double readmitTolerance(const UwbEkfParams& params);

/// The std along the major axis of the position of the constant-velocity block `p` ([x y vx vy])
/// predicted `dt` ahead (covariance only: F P F^T + Q), for the restart after an outage.
double predictedPositionStd(const Eigen::Matrix4d& p, double dt, const UwbEkfParams& params);

/// uwb-ekf, and the base of every range filter: N = 4, the primary tag's position and velocity
/// [x y vx vy]; N = 6, the robot's pose and rates [x y vx vy theta omega] from every tag (see
/// the top of this file).
template <int N>
class UwbEkfT : public UwbEstimator {
  static_assert(N == 4 || N == 6, "the range filters' state is [x y vx vy] or [x y vx vy th w]");

 public:
  static constexpr bool kMultitag = N == 6;
  /// The heading std under which the heading counts as observed (heading_valid) [rad]: 30
  /// degrees. A start from one tag's epoch has pi; the start pose's is start_sigma_yaw. How well
  /// it is known is the covariance's to say: heading_valid means observed, as for every method.
  static constexpr double kObservedHeadingStd = 30.0 * M_PI / 180.0;
  static constexpr int kTheta = 4;  ///< the heading's index in the state (N = 6)
  static constexpr int kOmega = 5;
  using State = kalman::Vec<N>;
  using Covariance = kalman::Mat<N, N>;
  using Jacobian = kalman::Mat<1, N>;

  UwbEkfT(const UwbEkfParams& params, const EstimatorContext& context);
  UwbEkfT(const UwbEkfT&) = delete;  // start_'s callbacks hold `this`
  UwbEkfT& operator=(const UwbEkfT&) = delete;

  /// The measured 3D distance from the tag to `anchor`, and, when asked, its Jacobian. N = 4:
  /// the tag at (x, y, tag height), [dx/h, dy/h, 0, 0] (PF-IBAS paper eq. (3)-(4) before the
  /// height projection); N = 6: the tag at the robot's pose plus its lever arm, the heading's
  /// column included.
  static double rangeModel(const State& x, const Eigen::Vector3d& tag_on_robot,
                           const Eigen::Vector3d& anchor, Jacobian* hj = nullptr);
  static double rangeModel(const State& x, const AcceptedRange& r, Jacobian* hj = nullptr) {
    return rangeModel(x, r.measurement.tag_on_robot, r.anchor, hj);
  }

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::vector<PoseEstimate> doFinishAll() override;
  std::optional<PoseEstimate> doFinish() override;
  void reset() override;
  /// Called when the state (re)starts (the adaptive filter restarts its noise statistics).
  virtual void onStart() {}
  /// Predicts to the range's time and updates with it: predictTo, predictRange, the gate and the
  /// quarantine (admit), correctWithRange. False when the range was not used.
  virtual bool updateWithRange(const AcceptedRange& r);

  /// A range's prediction at the predicted state: its value and the innovation variance
  /// (R included).
  struct RangePrediction {
    double z = 0.0;
    double s = 0.0;
  };
  /// The time update to t (t > t_): x <- F x, P <- F P F^T + Q (transition).
  virtual void predictTo(double t);
  /// EKF: h(x) and H P H^T + R with the Jacobian of rangeModel (kept for correctWithRange).
  virtual RangePrediction predictRange(const AcceptedRange& r);
  /// EKF: the Joseph update with the innovation y = range - prediction.z.
  virtual void correctWithRange(const AcceptedRange& r, double y, const RangePrediction& pred);
  /// The EKF's update with the Jacobian of the last EKF predictRange (UwbEkfT::predictRange),
  /// innovation y and range noise variance `r_var`; with `blind` (a unit vector in the plane),
  /// the Jacobian's position part less its component along it: the range then moves the state
  /// along `blind` only through the covariance's correlations.
  void linearCorrect(double y, double r_var, const Eigen::Vector2d* blind = nullptr);
  /// The update of a range that folds over the points (rangeFold): linearCorrect blind along the
  /// fold (event blind_across_fold), or at the mean when the fold's side is known (event
  /// linearised_at_fold).
  void foldCorrect(double y, double r_var, const RangeFold& fold) {
    ++stats_.events[fold.event()];
    linearCorrect(y, r_var, fold.side_known ? nullptr : &fold.axis);
  }
  /// rangeFold's `side_sigmas`: the gate's, sqrt(gate) range stds.
  double sideSigmas() const { return std::sqrt(params_.gate); }
  /// Removes from the Jacobian's position part its component along the unit vector `axis` (the
  /// fold's blind update, rangeFold).
  static void blindAlong(Jacobian& h, const Eigen::Vector2d& axis) {
    h.template head<2>() -= h.template head<2>().dot(axis) * axis.transpose();
  }
  /// The gate's and the quarantine's verdict on this range's link with this innovation; a
  /// refused range is counted.
  bool admit(const AcceptedRange& r, double innovation, bool in_gate);
  /// The range's link: (anchor, 0) with one tag, (anchor, tag) with several; the key of the
  /// quarantine and of the adaptive filters' per-link noise statistics.
  RangeQuarantine::Link link(const AcceptedRange& r) const {
    return {r.measurement.anchor_id, kMultitag ? r.measurement.tag_id : 0};
  }
  /// Reports a link's noise statistics as its anchor's (estimated_noise is per anchor): every
  /// link's with one tag, the primary tag's with several.
  void reportNoise(const RangeQuarantine::Link& l, const NoiseEstimate& estimate) {
    if (!kMultitag || l.second == primary_tag_) stats_.estimated_noise[l.first] = estimate;
  }
  /// The point filters' bound on the heading's spread (N = 6): the 2N cubature or unscented
  /// points lie sqrt(N) sigma_theta about the heading, and beyond +-pi they wrap round the circle
  /// and their moments say nothing of it, so the heading can never be learnt again. A heading std
  /// above kMaxPointHeadingStd (60 deg: the points within +-147 deg) is scaled down to it, its
  /// correlations kept (the state's heading rescaled); counted as heading_std_bounded. True when
  /// `p` was changed.
  static constexpr double kMaxPointHeadingStd = 60.0 * M_PI / 180.0;
  bool boundHeadingSpread(Covariance& p);
  /// The transition over dt: F and Q of the constant-velocity model (N = 6: and of the white
  /// angular acceleration), the densities scaled by `scale`.
  void transition(double dt, Covariance& f, Covariance& q, double scale = 1.0) const;

  double dt(double t) const { return t - t_; }
  double rangeVariance() const { return params_.front.sigmaValue() * params_.front.sigmaValue(); }
  /// The variance of this range: the method's, scaled by what an NLOS model said of it.
  double rangeVariance(const AcceptedRange& r) const { return rangeVariance() * r.variance_scale; }

  UwbEkfParams params_;
  double t_ = 0.0;
  State x_ = State::Zero();
  Covariance p_ = Covariance::Identity();

 private:
  Jacobian hj_;  ///< the Jacobian of the last predictRange
  bool initialise(const AcceptedRange& r);
  /// One event through the filter (after the learning start).
  std::optional<PoseEstimate> step(const Event& event);
  /// The learnt range model and q into the filter.
  void learn(const EstimatorStatistics& learnt);
  PoseEstimate output(const Eigen::Vector3d& tag_on_robot) const;

  int primary_tag_ = 0;
  std::optional<Eigen::Vector3d> start_pose_;  ///< used once, for the first start
  EpochBuffer init_epochs_;
  HeadingFromMotion heading_;  ///< N = 4: the heading from the direction of motion
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  /// The last max_gated ranges since the start: their anchor and whether the filter used them.
  struct RecentRange {
    int anchor;
    bool used;
    double innovation;  ///< [m]; NaN when the filter did not judge it
  };
  std::deque<RecentRange> recent_;
  double last_innovation_ = 0.0;  ///< of the range being judged (admit)
  /// Whether the last max_gated ranges were mostly refused and the used ones all came from one
  /// anchor, while others answered: a position that one range pins to a circle, and the filter
  /// lost on it.
  bool leansOnOneAnchor() const;
  /// N = 4: whether the filter crossed to the mirror image of its position across the line
  /// through the two anchors it used, on the evidence of a third that it refused (the rule is at
  /// its definition); the state, the quarantine and onStart() follow when it did.
  bool crossToTheMirror(const AcceptedRange& r);
  /// N = 4: after a used range of `anchor`, which anchor pairs' lines the state has come near
  /// since an anchor off the line was last used (crossToTheMirror).
  void trackNearLines(int anchor, const Eigen::Vector2d& anchor_xy);
  /// The line through two anchors (ids a < b).
  struct AnchorLine {
    int a, b;
    Eigen::Vector2d point, along;  ///< a's position, the unit direction
    bool near = false;  ///< the state came within 3 sigma of it since an anchor off it was used
    Eigen::Vector2d normal() const { return {-along.y(), along.x()}; }
  };
  std::map<int, Eigen::Vector2d> anchor_xy_;  ///< every anchor used since the start
  std::vector<AnchorLine> lines_;             ///< one per pair of anchor_xy_
  int mirror_agreed_ = 0;                     ///< refused ranges in a row the mirror explains
  RangeQuarantine quarantine_;  ///< by link
  RangeNoiseModel noise_;       ///< the learnt bias and scale each range is corrected by
  LearningStart start_;
  LearningStart::Learnt learnt_ = [this](const EstimatorStatistics& s) { learn(s); };
  LearningStart::Step step_ = [this](const Event& e) { return step(e); };
};

extern template class UwbEkfT<4>;
extern template class UwbEkfT<6>;

using UwbEkf = UwbEkfT<4>;
using UwbEkfMultitag = UwbEkfT<6>;

/// A range filter's estimator for `context`: Filter<6> on every tag when the robot carries two
/// tags or more and `tags` is auto, else Filter<4> on the primary tag.
template <template <int> class Filter, class Params>
std::unique_ptr<Estimator> makeRangeFilter(const Params& params, RobotTags tags,
                                           const EstimatorContext& context) {
  if (tagUse(tags, context) == TagUse::kAll) return std::make_unique<Filter<6>>(params, context);
  return std::make_unique<Filter<4>>(params, context);
}

}  // namespace uwbloc::loc
