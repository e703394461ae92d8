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
#include "uwbloc/localization/methods/fix_filter.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct UwbKfParams {
  FixFilterParams fix;        ///< the fix, the gate, the restart, the learning (fix_filter.hpp)
  AutoDouble q;               ///< white-acceleration spectral density [m^2/s^3]; auto: learnt
  double accel_psd = 0.1;     ///< the q in force: q's value, or the learnt one (not a key)
  double velocity_tau = 5.0;  ///< velocity correlation time [s]; 0 = constant velocity

  template <class V>
  void visit(V&& v) {
    fix.visit(v);
    v("q", q,
      "white-acceleration spectral density [m^2/s^3]; auto: learnt at the start when calib > 0 "
      "(only ever raised from 0.1), else 0.1");
    v("tau", velocity_tau, "velocity correlation time [s]; 0 = constant velocity");
  }
};

class UwbKf : public FixFilter {
 public:
  UwbKf(const UwbKfParams& params, const EstimatorContext& context);

 protected:
  void start(const uwb::Fix& fix) override;
  bool predictAndUpdate(const uwb::Fix& fix, double dt) override;
  PoseEstimate pose(double t, const Eigen::Vector3d& tag_on_robot) override;
  /// The range model (EpochUwbEstimator) and q (raised only; range_noise.hpp).
  void learn(const EstimatorStatistics& learnt) override;

  UwbKfParams params_;
  Eigen::Vector4d x_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d p_ = Eigen::Matrix4d::Identity();

 private:
  HeadingFromMotion heading_;
};

}  // namespace uwbloc::loc
