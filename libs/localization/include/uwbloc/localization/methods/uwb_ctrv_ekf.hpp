// uwb-ctrv-ekf: the mobile-node paper's filter (mobile-node-assisted-uwb.txt, §2.1-2.3): an EKF
// with the constant turn rate and velocity model, state [x y v theta omega] of the tag
// (ctrvPredict, motion_models.hpp), measuring the per-epoch least-squares fix (§2.2, H = [I 0],
// R the fix's covariance), behind the range front end's increment-queue gate (§2.1, on by
// default: `iq`). It starts from the first consistent fix at rest, with the start pose's heading
// when the run has one. The update is the toolkit's (innovation, chi-square gate, Joseph form).
#pragma once

#include <Eigen/Core>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/methods/fix_filter.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct UwbCtrvEkfParams {
  /// The fix (least squares, §2.2), the gate and the restart (fix_filter.hpp).
  FixFilterParams fix = [] {
    FixFilterParams f;
    f.solver = MultilaterationSolver::kLinearLS;
    return f;
  }();
  double sigma_a = 0.5;    ///< longitudinal acceleration std [m/s^2]
  double sigma_yaw = 0.5;  ///< yaw acceleration std [rad/s^2]

  template <class V>
  void visit(V&& v) {
    fix.visit(v);
    v("sigma_a", sigma_a, "longitudinal acceleration std [m/s^2]");
    v("sigma_yaw", sigma_yaw, "yaw acceleration std [rad/s^2]");
  }
};

class UwbCtrvEkf : public FixFilter {
 public:
  UwbCtrvEkf(const UwbCtrvEkfParams& params, const EstimatorContext& context);

 protected:
  void start(const uwb::Fix& fix) override;
  bool predictAndUpdate(const uwb::Fix& fix, double dt) override;
  PoseEstimate pose(double t, const Eigen::Vector3d& tag_on_robot) override;
  /// The range model (EpochUwbEstimator) and the start's speed spread: the learnt path's mean
  /// squared speed, when above 1 m^2/s^2.
  void learn(const EstimatorStatistics& learnt) override;

 private:
  UwbCtrvEkfParams params_;
  double start_speed_var_ = 1.0;  ///< [m^2/s^2]
  std::optional<double> start_heading_;
  Eigen::Matrix<double, 5, 1> x_ = Eigen::Matrix<double, 5, 1>::Zero();
  Eigen::Matrix<double, 5, 5> p_ = Eigen::Matrix<double, 5, 5>::Identity();
};

}  // namespace uwbloc::loc
