// uwb-kf: linear Kalman filter, constant-velocity state [x y vx vy] of the tag, measuring the
// position given by per-epoch multilateration (loosely coupled; the greenhouse paper's setup):
//   state eq. (1), X_k = F X_{k-1} + W_k with F of eq. (2)-(3) (here with an optional velocity
//   decay), measurement Z_k = H X_k + V_k of eq. (6) with H = [I 0] and R the fix's covariance,
//   and the filter of eq. (15) without the Sage-Husa terms q̂, r̂ (the Joseph form replaces its
//   last line). The fix itself is eq. (9)-(14) (solver=ls), Gauss-Newton or Chan.
#pragma once

#include <Eigen/Core>
#include <string>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct UwbKfParams {
  RangeFrontEndParams front;
  AutoDouble epoch_window;  ///< ranges within this span form one epoch [s]; auto: the data's rate
  /// Multilateration for the measurement: ls (the greenhouse paper), gn or chan.
  MultilaterationSolver solver = MultilaterationSolver::kGaussNewton;
  double accel_psd = 0.1;      ///< q, white-acceleration spectral density [m^2/s^3]
  double velocity_tau = 5.0;   ///< velocity correlation time [s]; 0 = constant velocity
  double gate = 13.8;          ///< chi-square gate on the 2D innovation (99.9 %, 2 dof)
  int max_gated = 5;           ///< consecutive gated fixes before re-initialising
  double init_residual = 0.5;  ///< largest residual norm of a fix used to (re)initialise [m]

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("window", epoch_window,
      "epoch window [s], or auto (one round of ranges from the data's rate)");
    v("solver", solver, "multilateration solver for the measurement: ls, gn, chan");
    v("q", accel_psd, "white-acceleration spectral density [m^2/s^3]");
    v("tau", velocity_tau, "velocity correlation time [s]; 0 = constant velocity");
    v("gate", gate, "chi-square gate on the position innovation (2 dof)");
    v("max_gated", max_gated, "consecutive gated fixes before re-initialising");
    v("init_residual", init_residual, "largest residual norm of an initialising fix [m]");
  }
};

class UwbKf : public EpochUwbEstimator {
 public:
  UwbKf(const UwbKfParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) override;
  void reset() override { initialised_ = false; }
  /// Starts the state from a fix (the adaptive filters also start their noise statistics).
  virtual void start(const uwb::Fix& fix);
  /// Predicts over dt and updates with the fix; false when the update was refused (gated).
  virtual bool predictAndUpdate(const uwb::Fix& fix, double dt);

  UwbKfParams params_;
  Eigen::Vector4d x_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d p_ = Eigen::Matrix4d::Identity();

 private:
  HeadingFromMotion heading_;
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  double t_ = 0.0;
};

}  // namespace uwbloc::loc
