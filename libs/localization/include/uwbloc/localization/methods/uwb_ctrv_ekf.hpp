// uwb-ctrv-ekf: the mobile-node paper's filter (mobile-node-assisted-uwb.txt, §2.1-2.3): an EKF
// with the constant turn rate and velocity model, state [x y v theta omega] of the tag
// (ctrvPredict, motion_models.hpp), measuring the per-epoch fix (H = [I 0], R the fix's
// covariance), behind the range front end's increment-queue gate (§2.1, on by default: `iq`).
// The fix is Gauss-Newton's by default; the paper's least squares (§2.2, solver=ls) left the
// heading swinging with its lateral errors (Hanyang LOS A1 1.909 against 1.330 m, Plaza2 9.2
// against 2.6 m). It starts from the first consistent fix at rest, with the start pose's heading
// when the run has one; without one, at every restart, and when the course's variance has grown
// past a full turn, the speed and course come from a straight-line fit of the fixes once they
// have moved (startCourse). The update is the toolkit's (innovation, chi-square gate, Joseph
// form).
#pragma once

#include <Eigen/Core>
#include <deque>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/methods/fix_filter.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct UwbCtrvEkfParams {
  /// The fix (Gauss-Newton; solver=ls: the paper's least squares, §2.2), the gate and the
  /// restart (fix_filter.hpp).
  FixFilterParams fix;
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
  /// Without a course: the position alone until the fixes have moved; false when gated.
  bool trackUntilMoved(const uwb::Fix& fix, double dt);
  /// Speed and course from the fixes since the start once they have moved; false before.
  bool startCourse();

  struct PendingFix {
    double t;                  ///< since the start [s]
    Eigen::Vector2d position;  ///< the fix
    double variance;           ///< its per-axis variance [m^2]
  };
  UwbCtrvEkfParams params_;
  bool started_ = false;         ///< a start has happened (the start pose's heading is used up)
  bool course_pending_ = false;  ///< started without a course: trackUntilMoved
  static constexpr size_t kMaxPending = 50;  ///< fixes the course fit keeps (a robot at rest)
  std::deque<PendingFix> pending_;           ///< the latest fixes since that start
  double start_speed_var_ = 1.0;  ///< [m^2/s^2]
  std::optional<double> start_heading_;
  Eigen::Matrix<double, 5, 1> x_ = Eigen::Matrix<double, 5, 1>::Zero();
  Eigen::Matrix<double, 5, 5> p_ = Eigen::Matrix<double, 5, 5>::Identity();
};

}  // namespace uwbloc::loc
