// uwb-ctrv-ekf: the mobile-node paper's filter (mobile-node-assisted-uwb.txt, §2.1-2.3): an EKF
// with the constant turn rate and velocity model, state [x y v theta omega] of the tag
// (ctrvPredict, motion_models.hpp), measuring the per-epoch fix (H = [I 0], R the fix's
// covariance), behind the range front end's increment-queue gate (§2.1, on by default: `iq`).
// The fix is Gauss-Newton's by default; the paper's least squares (§2.2, solver=ls) left the
// heading swinging with its lateral errors (Hanyang LOS A1 1.909 against 1.330 m, Plaza2 9.2
// against 2.6 m). At rest (at the start, at every restart, and whenever the speed falls within
// 2 sigma of zero or the course's variance grows past a full turn) the course is unobservable,
// and the linearised CTRV model would spread the position along the held course only: the state
// is then a constant-velocity track of the position and a Cartesian velocity, and the CTRV state
// is taken from that velocity once its speed stands beyond 3 sigma (startCourse; event
// `course_lost` on each return to rest). The update is the toolkit's (innovation, chi-square
// gate, Joseph form).
#pragma once

#include <Eigen/Core>

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
  /// At rest: a constant-velocity filter of the position and a Cartesian velocity (startCourse
  /// leaves it once the tag moves); false when gated.
  bool trackAtRest(const uwb::Fix& fix, double dt);
  /// No course: to track at rest from the position, the velocity zero with the speed's spread.
  void loseCourse();
  /// The CTRV state from the Cartesian velocity once its speed is beyond 3 sigma.
  void startCourse();

  UwbCtrvEkfParams params_;
  bool started_ = false;         ///< a start has happened (the start pose's heading is used up)
  bool at_rest_ = true;          ///< trackAtRest: the state is cv_x_, cv_p_
  Eigen::Vector4d cv_x_ = Eigen::Vector4d::Zero();  ///< at rest: x, y, vx, vy
  Eigen::Matrix4d cv_p_ = Eigen::Matrix4d::Identity();
  double start_speed_var_ = 1.0;  ///< [m^2/s^2]
  std::optional<double> start_heading_;
  Eigen::Matrix<double, 5, 1> x_ = Eigen::Matrix<double, 5, 1>::Zero();
  Eigen::Matrix<double, 5, 5> p_ = Eigen::Matrix<double, 5, 5>::Identity();
};

}  // namespace uwbloc::loc
