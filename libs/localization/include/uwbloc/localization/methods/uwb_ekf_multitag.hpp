// uwb-ekf on a robot with two tags or more: the robot's pose and its rates, state
// [x y vx vy theta omega] (white acceleration with uwb-ekf's velocity decay, white angular
// acceleration), updated by each range of every tag through its lever arm l_k:
//
//   r = || ((x, y) + R(theta) l_k_xy, z_k) - a ||,
//   dr/dtheta = (d_x (-s l_x - c l_y) + d_y (c l_x - s l_y)) / r,   d = tag - a.
//
// Two tags a known distance apart observe the heading from the ranges alone, so the heading is
// known while the robot stands still, which the single-tag uwb-ekf (heading from the direction
// of motion) cannot know. Everything else is uwb-ekf's: the learning start, the gate, the
// quarantine (per anchor-tag link here: a body blocks one tag's line of sight, not the anchor's),
// the restart after too many gated ranges or an outage. Its start: the start pose (position std
// start_sigma, heading std start_sigma_yaw), or an epoch of ranges solved by uwb-multitag's
// Gauss-Newton (solveMultitag); the heading counts as observed (heading_valid) while its std is
// below kObservedHeadingStd.
#pragma once

#include <Eigen/Core>

#include "uwbloc/localization/methods/uwb_ekf.hpp"

namespace uwbloc::loc {

/// Which of the robot's tags uwb-ekf reads.
enum class EkfTags { kAuto, kPrimary };
constexpr std::array<EnumName<EkfTags>, 2> enumNames(EkfTags) {
  return {{{EkfTags::kAuto, "auto"}, {EkfTags::kPrimary, "primary"}}};
}

/// uwb-ekf's keys: the single-tag filter's, and those of its multi-tag form.
struct UwbEkfMethodParams {
  UwbEkfParams ekf;
  EkfTags tags = EkfTags::kAuto;
  double yaw_accel_psd = 1.0;     ///< white angular acceleration density [rad^2/s^3]
  double start_sigma_yaw = 20.0;  ///< heading std at the start pose [deg]

  template <class V>
  void visit(V&& v) {
    ekf.visit(v);
    v("tags", tags,
      "auto: every tag on the robot when it carries two or more (the pose and heading from the "
      "lever arms), else the primary tag; primary: the primary tag's ranges only");
    v("yaw_accel_psd", yaw_accel_psd,
      "two tags or more: white angular acceleration density [rad^2/s^3]");
    v("start_sigma_yaw", start_sigma_yaw, "two tags or more: heading std at the start pose [deg]");
  }
};

/// uwb-ekf's estimator for `params` in `context`: UwbEkfMultitag when the robot carries two tags
/// or more and tags=auto, else UwbEkf on the primary tag.
std::unique_ptr<Estimator> makeUwbEkf(const UwbEkfMethodParams& params,
                                      const EstimatorContext& context);

class UwbEkfMultitag : public UwbEstimator {
 public:
  /// The heading std under which the heading counts as observed (heading_valid) [rad]: 30
  /// degrees. A start from one tag's epoch has pi; the start pose's is start_sigma_yaw. How well
  /// it is known is the covariance's to say: heading_valid means observed, as for every method.
  static constexpr double kObservedHeadingStd = 30.0 * M_PI / 180.0;
  using State = Eigen::Matrix<double, 6, 1>;  ///< [x y vx vy theta omega]
  using Covariance = Eigen::Matrix<double, 6, 6>;

  UwbEkfMultitag(const UwbEkfMethodParams& params, const EstimatorContext& context);
  UwbEkfMultitag(const UwbEkfMultitag&) = delete;  // start_'s callbacks hold `this`
  UwbEkfMultitag& operator=(const UwbEkfMultitag&) = delete;

  /// The range from tag `tag_on_robot` of the robot at `x` to `anchor`, and, when asked, its
  /// Jacobian with respect to the state. Exposed for tests.
  static double rangeModel(const State& x, const Eigen::Vector3d& tag_on_robot,
                           const Eigen::Vector3d& anchor,
                           Eigen::Matrix<double, 1, 6>* jacobian = nullptr);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::vector<PoseEstimate> doFinishAll() override;
  std::optional<PoseEstimate> doFinish() override;
  void reset() override;

 private:
  std::optional<PoseEstimate> step(const Event& event);
  bool initialise(const AcceptedRange& r);
  void predictTo(double t);
  /// The gate, the quarantine and the update; false when the range was not used.
  bool update(const AcceptedRange& r);
  PoseEstimate output() const;
  void learn(const EstimatorStatistics& learnt);
  double rangeVariance(const AcceptedRange& r) const;

  UwbEkfMethodParams params_;
  double t_ = 0.0;
  State x_ = State::Zero();
  Covariance p_ = Covariance::Identity();
  std::optional<Eigen::Vector3d> start_pose_;  ///< used once, for the first start
  EpochBuffer init_epochs_;
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  RangeQuarantine quarantine_;  ///< by anchor-tag link
  RangeNoiseModel noise_;
  LearningStart start_;
  LearningStart::Learnt learnt_ = [this](const EstimatorStatistics& s) { learn(s); };
  LearningStart::Step step_ = [this](const Event& e) { return step(e); };
};

}  // namespace uwbloc::loc
