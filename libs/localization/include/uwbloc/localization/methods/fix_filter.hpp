// The loosely coupled filters' shared flow: each epoch's ranges are multilaterated into a fix;
// the first consistent fix starts the filter; each later one is a prediction over the time since
// the last and an update with the fix; `max_gated` refused updates in a row restart the filter at
// the next consistent fix. uwb-kf, uwb-akf (mode=fix) and uwb-ctrv-ekf differ in their state,
// model and update only.
#pragma once

#include <Eigen/Core>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct FixFilterParams {
  RangeFrontEndParams front;
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
      : EpochUwbEstimator(params.front, context, params.epoch_window, TagUse::kPrimary,
                          params.learning, q),
        fix_(params) {}
  std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) final;
  void reset() override { initialised_ = false; }

  /// Starts the state from a fix.
  virtual void start(const uwb::Fix& fix) = 0;
  /// Predicts over dt and updates with the fix; false when the update was refused (gated).
  virtual bool predictAndUpdate(const uwb::Fix& fix, double dt) = 0;
  /// The pose estimate at time t from the state.
  virtual PoseEstimate pose(double t, const Eigen::Vector3d& tag_on_robot) = 0;

  const FixFilterParams& fixParams() const { return fix_; }

 private:
  FixFilterParams fix_;
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  double t_ = 0.0;
};

}  // namespace uwbloc::loc
