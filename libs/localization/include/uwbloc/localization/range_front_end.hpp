// What every UWB method does to a range before using it: validity checks, anchor look-up,
// time order, the optional increment-queue gate, and the height projection of eq. (3).
#pragma once

#include <array>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/fix_continuity.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/nlos/model.hpp"
#include "uwbloc/uwb/gates.hpp"
#include "uwbloc/uwb/multilateration.hpp"
#include "uwbloc/uwb/rigid_fit.hpp"

namespace uwbloc::loc {

/// What the front end does with a range that an NLOS model judged (nlos_model=PATH).
enum class NlosUse {
  kWeight,   ///< widen the range's variance by 1 / (1 - P(NLOS)), P capped at 0.99
  kCorrect,  ///< subtract the predicted error; add its variance to the range's
  kReject,   ///< drop the range when P(NLOS) >= nlos_reject
};
constexpr std::array<EnumName<NlosUse>, 3> enumNames(NlosUse) {
  return {
      {{NlosUse::kWeight, "weight"}, {NlosUse::kCorrect, "correct"}, {NlosUse::kReject, "reject"}}};
}

/// The range std a method starts from when `sigma=auto` and the data has not told it yet [m].
constexpr double kStartRangeSigma = 0.15;

struct RangeFrontEndParams {
  AutoDouble sigma;            ///< range standard deviation [m]; auto: estimated from the data
  double max_range = 100.0;    ///< longer ranges are rejected [m]
  bool increment_gate = true;  ///< apply the increment-queue gate
  int iq_length = 5;           ///< increment queue length n
  double iq_zeta = 3.0;        ///< increment queue scale ζ
  double iq_max_speed = 2.0;   ///< fastest plausible tag speed [m/s]
  double iq_floor = 0.3;       ///< increment tolerance for noise [m]
  std::string nlos_model;      ///< NLOS model file (uwbloc nlos train); empty: none
  NlosUse nlos_use = NlosUse::kWeight;
  double nlos_reject = 0.9;    ///< P(NLOS) at which nlos_use=reject drops a range [-]
  bool mobile_anchors = true;  ///< a still mobile node serves as a temporary anchor
  int mobile_window = 20;      ///< the node's last fixes its stillness is judged on
  AutoDouble
      mobile_var;  ///< per-axis variance under which it is still [m^2]; auto: 4x its fixes' own

  /// The fixed std, or the starting one when auto.
  double sigmaValue() const { return sigma.value.value_or(kStartRangeSigma); }

  template <class V>
  void visit(V&& v) {
    v("sigma", sigma,
      "range standard deviation [m]; auto: estimated from the residuals where the method can "
      "(graph), else 0.15");
    v("max_range", max_range, "ranges beyond this are rejected [m]");
    v("iq", increment_gate, "increment-queue gate on/off");
    v("iq_n", iq_length, "increment queue length");
    v("iq_zeta", iq_zeta, "increment queue scale on the mean recent increment");
    v("iq_vmax", iq_max_speed, "increment queue: fastest plausible speed [m/s]");
    v("iq_floor", iq_floor, "increment queue: noise tolerance [m]");
    v("nlos_model", nlos_model,
      "NLOS model (JSON from 'uwbloc nlos train', 'model:' prefix optional) judging each range "
      "from its received and first-path power; empty: none");
    v("nlos_use", nlos_use,
      "what the model's judgement does: weight (variance / (1 - P(NLOS))), correct (subtract "
      "the predicted error) or reject (drop at nlos_reject)");
    v("nlos_reject", nlos_reject, "P(NLOS) at which nlos_use=reject drops a range");
    v("mobile", mobile_anchors,
      "a mobile node (another tag ranging to the anchors) whose last fixes hold still becomes a "
      "temporary anchor for the ranges to it (the mobile-node paper, section 3)");
    v("mobile_n", mobile_window, "mobile node: fixes in its stillness test (the paper's m)");
    v("mobile_var", mobile_var,
      "mobile node: per-axis variance of those fixes under which it is still [m^2] (the "
      "paper's eta); auto: 4 times the variance the fixes' own covariance predicts");
  }
};

/// The model that `params.nlos_model` names, from the context's resolver; none when the name is
/// empty. Throws ParamError when the context has no resolver or the model cannot judge a range.
std::shared_ptr<const nlos::Model> resolveNlosModel(const RangeFrontEndParams& params,
                                                    const EstimatorContext& context);

/// Which of the robot's tags a method takes. Methods whose state is the robot's pose predict a
/// range from any tag through its lever arm (kAll); methods that track one tag point take the
/// primary tag's ranges only (the lowest id the manifest lists, else tag 0) and count the
/// others as rejected (secondary_tag).
enum class TagUse { kPrimary, kAll };

/// The primary tag of a context: the lowest listed robot tag, else 0.
int primaryTag(const EstimatorContext& context);

/// The `tags` key of the UWB methods: auto reads every tag when the robot carries two or more,
/// primary the primary tag's ranges only.
enum class RobotTags { kAuto, kPrimary };
constexpr std::array<EnumName<RobotTags>, 2> enumNames(RobotTags) {
  return {{{RobotTags::kAuto, "auto"}, {RobotTags::kPrimary, "primary"}}};
}

/// What `tags` means for `context`: kAll when auto and the robot lists two tags or more.
TagUse tagUse(RobotTags tags, const EstimatorContext& context);

/// A range that passed the front end.
struct AcceptedRange {
  uwb::Range measurement;
  Eigen::Vector3d anchor;  ///< anchor position [m]
  double planar = 0.0;     ///< height-projected range, eq. (3) [m]
  /// The range's variance over the method's own (> 1: an NLOS model doubts it).
  double variance_scale = 1.0;
  /// What an NLOS model did to it ("nlos_weighted", ...), for the statistics; or null. The names
  /// fit std::string's small buffer: counting them allocates nothing per range.
  const char* nlos_decision = nullptr;
};

/// Mobile nodes as temporary anchors (the mobile-node paper, section 3): each node (a tag not on
/// the robot) is multilaterated from its own ranges to the fixed anchors, one fix per epoch
/// (a range to an anchor already in the epoch, or 0.5 s, closes it). When the last `window`
/// fixes vary less than the threshold in x and in y (the paper's variance test, taken robustly:
/// (1.4826 MAD)^2 about the median, as three anchors flip the odd fix to a mirror point), their
/// median is the anchor kMobileAnchorBase + the node's tag id; when they vary more, or the last
/// fix is over 2 s old, it is no anchor.
class MobileAnchors {
 public:
  MobileAnchors(int window, std::optional<double> variance, double sigma)
      : window_(std::max(window, 2)), variance_(variance), sigma_(sigma) {}
  /// A node's range to a fixed anchor (others are ignored).
  void add(const uwb::Range& range, const std::vector<uwb::Anchor>& fixed);
  /// The node as an anchor at time t, when it is still.
  std::optional<uwb::Anchor> anchor(int id, double t) const;
  /// The variance of a node's position: its fixes' scatter about their median over the window,
  /// (1.4826 MAD)^2, averaged over x and y [m^2]; 0 for an unknown node. The scatter of one fix,
  /// not of the median: the fixes' errors are correlated while the node stands still. The front
  /// end adds it to the variance of each range to the node.
  double positionVariance(int id) const;

 private:
  struct Node {
    std::vector<uwb::PlanarRange> epoch;
    std::vector<int> epoch_anchors;
    double epoch_t = 0.0, height = 0.0, last_fix_t = -1e300;
    std::vector<Eigen::Vector2d> fixes;    ///< ring of the last `window` fixes
    std::vector<Eigen::Vector2d> fix_var;  ///< their predicted per-axis variances
    size_t count = 0;
    bool still = false;
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    double mean_var = 0.0;  ///< positionVariance
  };
  void solve(Node& node);
  int window_;
  std::optional<double> variance_;
  double sigma_;
  std::map<int, Node> nodes_;
  std::vector<double> scratch_;  ///< one axis of the fixes, for their median and MAD
};

class RangeFrontEnd {
 public:
  /// `nlos`: the model named by params.nlos_model (resolveNlosModel), or none.
  RangeFrontEnd(const RangeFrontEndParams& params, std::vector<uwb::Anchor> anchors,
                std::shared_ptr<const nlos::Model> nlos = nullptr, TagUse tags = TagUse::kPrimary,
                int primary_tag = 0);
  /// Returns the accepted range, or the reason it was rejected.
  std::optional<AcceptedRange> accept(const uwb::Range& range, uwb::RejectReason* reason);
  const std::vector<uwb::Anchor>& anchors() const { return anchors_; }

 private:
  /// The NLOS model's judgement applied to an accepted range; false: reject it.
  bool judge(AcceptedRange& r);

  RangeFrontEndParams params_;
  std::shared_ptr<const nlos::Model> nlos_;
  /// A centred model's environment: the medians of the ranges received so far.
  std::optional<nlos::RunningCentre> centre_;
  std::vector<uwb::Anchor> anchors_;
  uwb::IncrementQueueGate increments_;
  double last_t_ = -1e300;
  TagUse tags_ = TagUse::kPrimary;
  int primary_tag_ = 0;
  MobileAnchors mobile_;
};

/// Base of the UWB methods: owns the front end and turns an event into an accepted range,
/// counting each rejection against its anchor.
class UwbEstimator : public Estimator {
 protected:
  UwbEstimator(const RangeFrontEndParams& params, const EstimatorContext& context,
               TagUse tags = TagUse::kPrimary)
      : front_(params, context.anchors, resolveNlosModel(params, context), tags,
               primaryTag(context)) {}
  /// The accepted range carried by `event`; nothing for other events and rejected ranges.
  std::optional<AcceptedRange> acceptRange(const Event& event);
  /// A learnt model's correction of an accepted range (scale and bias), re-projected to the
  /// plane, before anything reads it; false, counted as below_height against its anchor, when
  /// the corrected range no longer reaches the anchor's height.
  bool correctRange(AcceptedRange& r, const RangeNoiseModel& model);

  RangeFrontEnd front_;
};

/// The per-epoch multilateration solvers.
enum class MultilaterationSolver { kLinearLS, kGaussNewton, kChan };
constexpr std::array<EnumName<MultilaterationSolver>, 3> enumNames(MultilaterationSolver) {
  return {{{MultilaterationSolver::kLinearLS, "ls"},
           {MultilaterationSolver::kGaussNewton, "gn"},
           {MultilaterationSolver::kChan, "chan"}}};
}

/// The `continuity` key of the methods that form a fix per epoch (fix_continuity.hpp).
inline constexpr const char* kContinuityHelp =
    "a fix the tag cannot have reached since the last kept one (iq_floor + v dt + 3 std, v = "
    "iq_vmax or 3 times the learnt RMS speed) is replaced by the reachable pair intersection "
    "that fits every range but one (a wrong range among three can fit the mirror image "
    "exactly); 0: every fix as it is";

/// The `tags` key of the same methods.
inline constexpr const char* kEpochTagsHelp =
    "auto: every tag when the robot carries two or more: each tag with three ranges or more is "
    "multilaterated on its own and the lever arms are fitted to those points (the pose and "
    "heading per epoch; a tag that disagrees with the others is left out), and an epoch where "
    "fewer than two tags fix takes the primary tag's ranges; primary: the primary tag's only";

/// The `deskew` key of the same methods.
inline constexpr const char* kDeskewHelp =
    "ranges taken one anchor at a time are moved to the epoch's mean time along the continuity "
    "track's velocity before the fix (range + u.v dt; its variance + (u^T C_v u) dt^2); needs "
    "continuity; 0: each range as taken";

/// Groups ranges into epochs: an epoch closes when a range arrives more than `window` seconds
/// after its first range, or a second range of an anchor-tag link already in it.
///
/// window = auto takes the span from the data's own rate: one round of ranges, from every anchor
/// seen, 1.2 (n_anchors - 1) times the median gap between consecutive ranges (over the last 64),
/// and never below kMinEpochWindow. Ranges that arrive together (one stamp per round, the MRPT
/// demo) give a zero gap and the shortest window; ranges that arrive one anchor at a time (CMU
/// Plaza, about 4 per second) give a window of about one second. With several tags the gaps
/// between consecutive ranges do not tell a round (tags that range together give zero gaps
/// between one anchor's ranges, tags that range in turn give a round several times one tag's):
/// the window is then 1.2 times the median span of the last 16 rounds, a round being the ranges
/// up to the first that repeats an anchor-tag link, and never below kMinEpochWindow.
class EpochBuffer {
 public:
  static constexpr double kMinEpochWindow = 0.15;  ///< [s]
  explicit EpochBuffer(AutoDouble window) : window_(window) {}
  /// Adds a range; returns the epoch it closed, if any.
  std::optional<std::vector<AcceptedRange>> add(const AcceptedRange& r);
  /// Returns the open epoch, if any, and empties the buffer.
  std::optional<std::vector<AcceptedRange>> flush();
  /// The span in force [s].
  double window() const;

 private:
  AutoDouble window_;
  std::vector<AcceptedRange> open_;
  WindowMedian gaps_{64};  ///< the last gaps between consecutive ranges [s]
  double last_t_ = 0.0;
  std::vector<int> anchors_seen_;
  std::vector<int> tags_seen_;
  std::vector<std::pair<int, int>> round_links_;  ///< the open round's anchor-tag links
  double round_start_ = 0.0;                      ///< its first range's time [s]
  WindowMedian round_spans_{16};                  ///< the last closed rounds' spans [s]
};

/// An epoch of several tags' ranges (EpochUwbEstimator::tagsEpoch).
struct TagsEpoch {
  /// The robot's pose (x, y, heading) and its covariance, when two tags or more fixed and agree.
  std::optional<uwb::RigidFit> fit;
  /// The primary tag's point: at the fitted pose (its covariance through the lever arm, the
  /// root sum square of the fitted tags' residual norms), else from its own ranges; none when
  /// neither.
  std::optional<uwb::Fix> primary;
  /// The primary tag's lever arm (once one of its ranges has been seen: the fit needs it).
  Eigen::Vector3d primary_lever = Eigen::Vector3d::Zero();
};

/// Base of the per-epoch UWB methods: accepted ranges are grouped into epochs and each closed
/// epoch (and the last, open one at the end of the stream) goes to onEpoch().
///
/// With a learning start (`learning.calib` > 0 and something to learn: sigma=auto, calib_bias,
/// or a subclass's q=auto), the first seconds of ranges go to graph-uwb as well; its model then
/// corrects every range (scale, and biases with calib_bias) and widens the std in force,
/// rangeSigma() (range_noise.hpp), and subclasses take the rest in learn().
class EpochUwbEstimator : public UwbEstimator {
 public:
  EpochUwbEstimator(const EpochUwbEstimator&) = delete;  // start_'s callbacks hold `this`
  EpochUwbEstimator& operator=(const EpochUwbEstimator&) = delete;

 protected:
  /// `q`: the subclass's q key, when it has one (its auto also calls for learning).
  EpochUwbEstimator(const RangeFrontEndParams& params, const EstimatorContext& context,
                    AutoDouble window, TagUse tags = TagUse::kPrimary,
                    const RangeLearningParams& learning = {BiasMode::kOff, 0.0},
                    const AutoDouble* q = nullptr);
  std::optional<PoseEstimate> doProcess(const Event& event) final;
  std::vector<PoseEstimate> doFinishAll() final;
  std::optional<PoseEstimate> doFinish() final { return newestOfFinishAll(); }
  virtual std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) = 0;
  /// The learnt model (the learner's statistics) into the method: the range correction and the
  /// std; a subclass that learns more extends it.
  virtual void learn(const EstimatorStatistics& learnt);
  /// The range std in force: the method's, or the learnt one (widened only).
  double rangeSigma() const { return sigma_; }
  /// A method that estimates its noise itself (Sage-Husa) takes only the learnt range
  /// correction, and keeps its own std (and q) to start its estimates from.
  virtual bool estimatesOwnNoise() const { return false; }
  /// The epoch's fixes. With the primary tag read alone: its fix (epochFixOn its track). With
  /// every tag read (TagUse::kAll): each tag of the epoch multilaterated on its own the same way,
  /// against its own continuity track (deskewed along it with
  /// `deskew`), and the lever arms of two tags or more fitted to those points
  /// (uwb::fitRigidBody), each point's covariance taken at the range variance the tags' fixes
  /// show (the median of their residual variance over the last 201, once there are 5). A tag of
  /// four ranges or more whose own residual fails its chi-square test (n - 2 degrees of freedom,
  /// 99.9 %) is left out first (its ranges counted: tag_fix_left_out). Then, while the
  /// fit's chi-square (2n - 3 degrees of freedom) is beyond its 99.9 % point, the tag whose leaving
  /// out fits the others best is left out (counted the same) as long as two
  /// remain; two that disagree give no fit (event tags_fix_inconsistent). Without a fit the primary
  /// tag's own fix stands (unless it was left out), and the other tags' ranges are counted as
  /// unused (secondary_tag).
  TagsEpoch tagsEpoch(MultilaterationSolver solver, const std::vector<AcceptedRange>& epoch,
                      bool continuity, bool deskew);
  /// Whether the method reads every tag (tagUse of its `tags` key).
  bool readsEveryTag() const { return tags_ == TagUse::kAll; }
  /// `fix` of the epoch's tag from `planar`, checked for continuity (FixContinuity::check with
  /// `solve` and `offset`; the check starts from `seed`, the start pose's point, when the run has
  /// one). Its outcome and each range it leaves out are counted; no fix when it refuses the epoch.
  FixContinuity::Checked continuityChecked(const std::vector<AcceptedRange>& epoch,
                                           const uwb::Fix& fix,
                                           const std::vector<uwb::PlanarRange>& planar,
                                           const FixContinuity::Solver& solve,
                                           const Eigen::Vector2d& offset,
                                           const std::optional<Eigen::Vector2d>& seed);
  /// The start pose, when the run has one.
  const std::optional<Eigen::Vector3d>& initialPose() const { return initial_pose_; }
  /// The continuity check judges every range against its track (FixContinuityParams::every_range).
  void checkEveryRange() { primary_track_.continuity.checkEveryRange(); }

 private:
  /// One event after the learning start.
  std::optional<PoseEstimate> step(const Event& event);

  /// A tag's continuity track (fix_continuity.hpp), seeded from the start pose once.
  struct TagTrack {
    FixContinuity continuity;
    bool seeded = false;
  };
  /// The track of `tag`: the primary tag's, or another's, made on first use (fresh()).
  TagTrack& track(int tag);
  /// A tag's fix by `solver` from `planar` (toPlanar of its ranges `epoch`) at time `t` (the
  /// epoch's: with several tags, that of every tag's ranges); with `continuity`, checked against
  /// the tag's reach since the last fix on `track`, from the start pose's tag
  /// (fix_continuity.hpp), and with `deskew` as well, from the ranges moved to `t` along the
  /// track's velocity (deskewRanges) once it has one. Nothing when the solver fails or the check
  /// refuses the epoch; each is counted.
  std::optional<uwb::Fix> epochFixOn(TagTrack& track, MultilaterationSolver solver, double t,
                                     const std::vector<AcceptedRange>& epoch,
                                     std::vector<uwb::PlanarRange> planar, bool continuity,
                                     bool deskew);
  /// continuityChecked on `track`, the fix taken at time `t`.
  FixContinuity::Checked checkedOn(TagTrack& track, double t,
                                   const std::vector<AcceptedRange>& epoch, const uwb::Fix& fix,
                                   const std::vector<uwb::PlanarRange>& planar,
                                   const FixContinuity::Solver& solve,
                                   const Eigen::Vector2d& offset,
                                   const std::optional<Eigen::Vector2d>& seed);

  TagUse tags_;
  int primary_tag_;
  std::optional<Eigen::Vector3d> primary_lever_;  ///< once one of its ranges has been seen
  EpochBuffer epochs_;
  TagTrack primary_track_;                ///< the primary tag's (uwb-multitag: the robot's)
  std::map<int, TagTrack> other_tracks_;  ///< the other tags', with every tag read
  WindowMedian fix_variances_{201};       ///< tagsEpoch: recent tag fixes' residual variance
  std::optional<Eigen::Vector3d> initial_pose_;
  double initial_time_ = 0.0;
  bool sigma_auto_;
  BiasMode calib_bias_;
  double sigma_;
  RangeNoiseModel noise_;
  LearningStart start_;
  LearningStart::Learnt learnt_ = [this](const EstimatorStatistics& s) { learn(s); };
  LearningStart::Step step_ = [this](const Event& e) { return step(e); };
};

/// One fix from an epoch's planar ranges with the chosen solver.
uwb::Fix multilaterate(MultilaterationSolver solver, const std::vector<uwb::PlanarRange>& ranges);

/// Planar ranges of an epoch, ready for the multilateration solvers.
std::vector<uwb::PlanarRange> toPlanar(const std::vector<AcceptedRange>& epoch, double sigma);

/// The time an epoch's fix stands for: the mean of its ranges' stamps. A fix from ranges taken
/// one anchor at a time over the epoch's window is, to first order, where the tag was at their
/// mean time, not at the last range's (stamped there, the per-epoch fixes on CMU Plaza2, whose
/// vehicle moves at 3.3 m/s, lagged 0.4 s, 1.4 m along the path).
double epochTime(const std::vector<AcceptedRange>& epoch);

/// `planar` (toPlanar of `epoch`) moved to time t along `motion`: a range taken dt = t - t_i
/// before t, while the tag moved at velocity v, reads u.v dt less than it would at t (u: the unit
/// vector from the anchor to the tag at t, to first order), so it gains u.v dt, and its variance
/// gains (u^T C_v u) dt^2 for the velocity's uncertainty. v is the track's velocity shrunk by
/// (1 - tr C_v / |v|^2), nothing when that is not positive. Ranges taken at t are unchanged.
/// Without it, the fix from ranges one anchor at a time over a second is no point of the path: on
/// CMU Plaza2 (3.3 m/s, a range every 0.23 s) a range taken 0.3 s before the epoch's time reads
/// up to 1 m from what it would read then.
std::vector<uwb::PlanarRange> deskewRanges(const std::vector<AcceptedRange>& epoch,
                                           std::vector<uwb::PlanarRange> planar, double t,
                                           const FixContinuity::Motion& motion);

/// The Gauss-Newton fix a tracking filter starts from: the epoch's, when it solves and its
/// residual norm is within `max_residual` (otherwise some range of the epoch is wrong).
/// Nothing when not; the reason is counted in `stats` as `prefix` + the solver's status, or as
/// init_inconsistent_fix.
std::optional<uwb::Fix> consistentFix(const std::vector<AcceptedRange>& epoch, double sigma,
                                      double max_residual, EstimatorStatistics& stats,
                                      const std::string& prefix = "init_");

}  // namespace uwbloc::loc
