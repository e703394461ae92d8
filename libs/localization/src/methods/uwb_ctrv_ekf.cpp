#include "uwbloc/localization/methods/uwb_ctrv_ekf.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

UwbCtrvEkf::UwbCtrvEkf(const UwbCtrvEkfParams& params, const EstimatorContext& context)
    : FixFilter(params.fix, context), params_(params) {
  if (context.initial_pose) start_heading_ = context.initial_pose->z();
}

void UwbCtrvEkf::learn(const EstimatorStatistics& learnt) {
  FixFilter::learn(learnt);
  if (learnt.mean_square_speed) start_speed_var_ = std::max(1.0, *learnt.mean_square_speed);
}

// At rest at the fix; the heading from the start pose when known, else unknown (std pi).
void UwbCtrvEkf::start(const uwb::Fix& fix) {
  x_ << fix.position, 0.0, start_heading_.value_or(0.0), 0.0;
  p_.setZero();
  p_.topLeftCorner<2, 2>() = fix.covariance;
  p_(2, 2) = start_speed_var_;
  p_(3, 3) = start_heading_ ? 0.1 : M_PI * M_PI;
  p_(4, 4) = 0.25;
}

bool UwbCtrvEkf::predictAndUpdate(const uwb::Fix& fix, double dt) {
  // §2.3 predict: x = f(x), P = F P F^T + Q (CTRV, ctrvPredict).
  Eigen::Matrix<double, 5, 5> f, q;
  x_ = ctrvPredict(x_, dt, &f, &q, params_.sigma_a, params_.sigma_yaw);
  x_(3) = wrapAngle(x_(3));
  p_ = f * p_ * f.transpose() + q;
  // §2.3 correct: the fix measures the position (H = [I 0]); the toolkit's steps (1)-(6).
  Eigen::Matrix<double, 2, 5> h = Eigen::Matrix<double, 2, 5>::Zero();
  h.leftCols<2>().setIdentity();
  const auto inn = kalman::innovate<5, 2>(p_, fix.position - x_.head<2>(), h, fix.covariance);
  if (!kalman::inGate(inn, uwb::ChiSquareGate(params_.fix.gate))) {
    countRejection("kf_innovation_gate");
    return false;
  }
  kalman::josephUpdate<5, 2>(x_, p_, inn, h, fix.covariance);
  return true;
}

// The tag's course is the robot's heading while it drives forwards.
PoseEstimate UwbCtrvEkf::pose(double t, const Eigen::Vector3d& tag_on_robot) {
  const double heading = x_(3) + (x_(2) < 0.0 ? M_PI : 0.0);
  PoseEstimate est =
      kalman::tagTrackPose(t, x_.head<2>(), p_.topLeftCorner<2, 2>(), tag_on_robot, heading);
  est.covariance(2, 2) = p_(3, 3);
  est.heading_valid = std::abs(x_(2)) > 0.05 && p_(3, 3) < 0.25;
  return est;
}

}  // namespace uwbloc::loc
