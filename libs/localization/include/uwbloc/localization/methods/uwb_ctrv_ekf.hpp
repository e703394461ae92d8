// uwb-ctrv-ekf: the mobile-node paper's filter (mobile-node-assisted-uwb.txt, §2.1-2.3): an EKF
// with the constant turn rate and velocity model, state [x y v theta omega] of the tag
// (ctrvPredict, motion_models.hpp), measuring the per-epoch least-squares fix (§2.2, H = [I 0],
// R the fix's covariance), behind the range front end's increment-queue gate (§2.1, on by
// default: `iq`). It starts from the first consistent fix at rest, with the start pose's heading
// when the run has one. The update is the toolkit's (innovation, chi-square gate, Joseph form).
#pragma once

#include <Eigen/Core>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct UwbCtrvEkfParams {
  RangeFrontEndParams front;
  AutoDouble epoch_window;  ///< ranges within this span form one epoch [s]; auto: the data's rate
  MultilaterationSolver solver = MultilaterationSolver::kLinearLS;  ///< §2.2: least squares
  double sigma_a = 0.5;        ///< longitudinal acceleration std [m/s^2]
  double sigma_yaw = 0.5;      ///< yaw acceleration std [rad/s^2]
  double gate = 13.8;          ///< chi-square gate on the 2D innovation (99.9 %, 2 dof)
  int max_gated = 5;           ///< consecutive gated fixes before re-initialising
  double init_residual = 0.5;  ///< largest residual norm of a fix used to (re)initialise [m]

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("window", epoch_window,
      "epoch window [s], or auto (one round of ranges from the data's rate)");
    v("solver", solver, "multilateration solver for the measurement: ls (the paper), gn, chan");
    v("sigma_a", sigma_a, "longitudinal acceleration std [m/s^2]");
    v("sigma_yaw", sigma_yaw, "yaw acceleration std [rad/s^2]");
    v("gate", gate, "chi-square gate on the position innovation (2 dof)");
    v("max_gated", max_gated, "consecutive gated fixes before re-initialising");
    v("init_residual", init_residual, "largest residual norm of an initialising fix [m]");
  }
};

class UwbCtrvEkf : public EpochUwbEstimator {
 public:
  UwbCtrvEkf(const UwbCtrvEkfParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) override;
  void reset() override { initialised_ = false; }

 private:
  UwbCtrvEkfParams params_;
  std::optional<double> start_heading_;
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  double t_ = 0.0;
  Eigen::Matrix<double, 5, 1> x_ = Eigen::Matrix<double, 5, 1>::Zero();
  Eigen::Matrix<double, 5, 5> p_ = Eigen::Matrix<double, 5, 5>::Identity();
};

}  // namespace uwbloc::loc
