#include "uwbloc/localization/methods/uwb_kf.hpp"

#include <Eigen/Dense>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

UwbKf::UwbKf(const UwbKfParams& params, const EstimatorContext& context)
    : FixFilter(params.fix, context, &params.q), params_(params) {
  params_.accel_psd = params.q.value.value_or(params.accel_psd);
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

void UwbKf::learn(const EstimatorStatistics& learnt) {
  FixFilter::learn(learnt);
  if (!estimatesOwnNoise())
    learnAccelPsd(learnt, params_.q, params_.velocity_tau, params_.accel_psd, stats_);
}

void UwbKf::start(const uwb::Fix& fix) { kalman::initialiseFromFix(fix, x_, p_); }

bool UwbKf::predictAndUpdate(const uwb::Fix& fix, double dt) {
  // Greenhouse eq. (15), lines 1-2: X = F X, P = F P F^T + Q.
  kalman::predictConstantVelocity(x_, p_, dt, params_.accel_psd, params_.velocity_tau);
  // Eq. (6): the fix measures the position, H = [I 0], R = the fix's covariance; eq. (15)
  // lines 3-6 are the toolkit's steps (1)-(6).
  Eigen::Matrix<double, 2, 4> h = Eigen::Matrix<double, 2, 4>::Zero();
  h.leftCols<2>().setIdentity();
  const auto inn = kalman::innovate<4, 2>(p_, fix.position - x_.head<2>(), h, fix.covariance);
  if (!kalman::inGate(inn, uwb::ChiSquareGate(params_.fix.gate))) {
    countRejection("kf_innovation_gate");
    return false;
  }
  kalman::josephUpdate<4, 2>(x_, p_, inn, h, fix.covariance);
  return true;
}

PoseEstimate UwbKf::pose(double t, const Eigen::Vector3d& tag_on_robot) {
  const double heading = heading_.update(x_.tail<2>());
  return kalman::tagTrackPose(t, x_.head<2>(), p_.topLeftCorner<2, 2>(), tag_on_robot, heading);
}

}  // namespace uwbloc::loc
