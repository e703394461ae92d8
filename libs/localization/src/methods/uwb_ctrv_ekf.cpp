#include "uwbloc/localization/methods/uwb_ctrv_ekf.hpp"

#include <cmath>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

UwbCtrvEkf::UwbCtrvEkf(const UwbCtrvEkfParams& params, const EstimatorContext& context)
    : EpochUwbEstimator(params.front, context.anchors, params.epoch_window), params_(params) {
  if (context.initial_pose) start_heading_ = context.initial_pose->z();
}

std::optional<PoseEstimate> UwbCtrvEkf::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const uwb::Fix fix = multilaterate(params_.solver, toPlanar(epoch, params_.front.sigmaValue()));
  if (!fix.ok()) {
    countRejection(std::string("epoch_") + uwb::toString(fix.status));
    return std::nullopt;
  }
  const double t = epochTime(epoch);
  const bool consistent = fix.residual_norm <= params_.init_residual;
  auto initialise = [&] {
    // At rest at the fix; the heading from the start pose when known, else unknown (std pi).
    x_ << fix.position, 0.0, start_heading_.value_or(0.0), 0.0;
    p_.setZero();
    p_.topLeftCorner<2, 2>() = fix.covariance;
    p_(2, 2) = 1.0;
    p_(3, 3) = start_heading_ ? 0.1 : M_PI * M_PI;
    p_(4, 4) = 0.25;
    t_ = t;
    initialised_ = true;
    gated_in_a_row_ = 0;
  };
  if (!initialised_) {
    if (!consistent) {
      countRejection("init_inconsistent_fix");
      return std::nullopt;
    }
    initialise();
  } else {
    // §2.3 predict: x = f(x), P = F P F^T + Q (CTRV, ctrvPredict).
    Eigen::Matrix<double, 5, 5> f, q;
    const double dt = std::max(0.0, t - t_);
    x_ = ctrvPredict(x_, dt, &f, &q, params_.sigma_a, params_.sigma_yaw);
    x_(3) = wrapAngle(x_(3));
    p_ = f * p_ * f.transpose() + q;
    t_ = std::max(t_, t);
    // §2.3 correct: the fix measures the position (H = [I 0]); the toolkit's steps (1)-(6).
    Eigen::Matrix<double, 2, 5> h = Eigen::Matrix<double, 2, 5>::Zero();
    h.leftCols<2>().setIdentity();
    const auto inn = kalman::innovate<5, 2>(p_, fix.position - x_.head<2>(), h, fix.covariance);
    if (!kalman::inGate(inn, uwb::ChiSquareGate(params_.gate))) {
      countRejection("kf_innovation_gate");
      if (++gated_in_a_row_ >= params_.max_gated && consistent) {
        ++stats_.resets;
        initialise();
      }
    } else {
      gated_in_a_row_ = 0;
      kalman::josephUpdate<5, 2>(x_, p_, inn, h, fix.covariance);
    }
  }
  // The tag's course is the robot's heading while it drives forwards.
  const double heading = x_(3) + (x_(2) < 0.0 ? M_PI : 0.0);
  PoseEstimate est = kalman::tagTrackPose(t_, x_.head<2>(), p_.topLeftCorner<2, 2>(),
                                          epoch.front().measurement.tag_on_robot, heading);
  est.covariance(2, 2) = p_(3, 3);
  est.heading_valid = std::abs(x_(2)) > 0.05 && p_(3, 3) < 0.25;
  return est;
}

}  // namespace uwbloc::loc
