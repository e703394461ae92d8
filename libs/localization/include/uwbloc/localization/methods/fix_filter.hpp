// The loosely coupled filters' shared flow: each epoch's ranges are multilaterated into a fix;
// the first consistent fix starts the filter; each later one is a prediction over the time since
// the last and an update with the fix; `max_gated` refused updates in a row restart the filter at
// the next consistent fix. uwb-kf, uwb-akf (mode=fix) and uwb-ctrv-ekf differ in their state,
// model and update only.
#pragma once

#include <Eigen/Core>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/kalman/kalman.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct FixFilterParams {
  RangeFrontEndParams front;
  /// Every tag (the fix from tagsEpoch, and the heading from the fits) or the primary tag's only;
  /// uwb-akf:mode=ranges reads it as uwb-ekf does.
  RobotTags tags = RobotTags::kAuto;
  double yaw_accel_psd = 1.0;  ///< two tags or more: the heading track's [rad^2/s^3]
  AutoDouble epoch_window;  ///< ranges within this span form one epoch [s]; auto: the data's rate
  /// Multilateration for the measurement: ls (the greenhouse and mobile-node papers), gn or chan.
  MultilaterationSolver solver = MultilaterationSolver::kGaussNewton;
  double gate = 13.8;          ///< chi-square gate on the 2D innovation (99.9 %, 2 dof)
  int max_gated = 5;           ///< consecutive gated fixes before re-initialising
  double init_residual = 0.5;  ///< largest residual norm of a fix used to (re)initialise [m]
  bool continuity = true;      ///< check each fix against the tag's reach (fix_continuity.hpp)
  bool deskew = true;          ///< ranges moved to the epoch's time along the track (deskewRanges)
  RangeLearningParams learning;  ///< calib, calib_bias: the learning start (range_noise.hpp)

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("tags", tags,
      "auto: every tag when the robot carries two or more: each tag with three ranges or more is "
      "multilaterated on its own and the lever arms are fitted to those points (a tag that "
      "disagrees with the others is left out); the filter tracks the primary tag's point from "
      "the fit and the heading comes from the fits (yaw_accel_psd); an epoch where fewer than "
      "two tags fix takes the primary tag's ranges; primary: the primary tag's only "
      "(uwb-akf:mode=ranges: as uwb-ekf's tags)");
    v("yaw_accel_psd", yaw_accel_psd,
      "two tags or more: the heading track's white angular acceleration density [rad^2/s^3]");
    v("window", epoch_window,
      "epoch window [s], or auto (one round of ranges from the data's rate)");
    v("solver", solver, "multilateration solver for the measurement: ls, gn, chan");
    v("gate", gate, "chi-square gate on the position innovation (2 dof)");
    v("max_gated", max_gated, "consecutive gated fixes before re-initialising");
    v("init_residual", init_residual, "largest residual norm of an initialising fix [m]");
    v("continuity", continuity, kContinuityHelp);
    v("deskew", deskew, kDeskewHelp);
    learning.visit(v);
  }
};

class FixFilter : public EpochUwbEstimator {
 protected:
  /// `q`: the subclass's q key, when it has one.
  FixFilter(const FixFilterParams& params, const EstimatorContext& context,
            const AutoDouble* q = nullptr)
      : EpochUwbEstimator(params.front, context, params.epoch_window, tagUse(params.tags, context),
                          params.learning, q),
        fix_(params),
        heading_track_(params.yaw_accel_psd) {}
  std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) final;
  void reset() override {
    initialised_ = false;
    heading_track_.reset();
  }

  /// Starts the state from a fix.
  virtual void start(const uwb::Fix& fix) = 0;
  /// Predicts over dt and updates with the fix; false when the update was refused (gated).
  virtual bool predictAndUpdate(const uwb::Fix& fix, double dt) = 0;
  /// The pose estimate at time t from the state.
  virtual PoseEstimate pose(double t, const Eigen::Vector3d& tag_on_robot) = 0;

  const FixFilterParams& fixParams() const { return fix_; }
  /// Whether the last fix was refused (gated) and no restart has happened since.
  bool lastFixRefused() const { return gated_in_a_row_ > 0; }

 private:
  /// The estimate with the heading track's heading, while its std is within 30 degrees: the
  /// robot's position moved to it about the tag's point, heading_valid.
  void useTrackedHeading(PoseEstimate& e, const Eigen::Vector3d& lever) const;

  FixFilterParams fix_;
  kalman::HeadingTrack heading_track_;
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  double t_ = 0.0;
};

}  // namespace uwbloc::loc
