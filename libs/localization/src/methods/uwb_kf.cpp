#include "uwbloc/localization/methods/uwb_kf.hpp"

#include <Eigen/Dense>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

UwbKf::UwbKf(const UwbKfParams& params, const EstimatorContext& context)
    : EpochUwbEstimator(params.front, context.anchors, params.epoch_window), params_(params) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

std::optional<PoseEstimate> UwbKf::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const auto planar = toPlanar(epoch, params_.front.sigmaValue());
  const uwb::Fix fix = multilaterate(params_.solver, planar);
  if (!fix.ok()) {
    countRejection(std::string("epoch_") + uwb::toString(fix.status));
    return std::nullopt;
  }
  const double t = epochTime(epoch);

  auto initialise = [&] {
    start(fix);
    t_ = t;
    initialised_ = true;
    gated_in_a_row_ = 0;
  };
  const bool consistent = fix.residual_norm <= params_.init_residual;
  if (!initialised_) {
    if (!consistent) {
      countRejection("init_inconsistent_fix");
      return std::nullopt;
    }
    initialise();
  } else {
    const double dt = std::max(0.0, t - t_);
    t_ = std::max(t_, t);
    if (!predictAndUpdate(fix, dt)) {
      if (++gated_in_a_row_ >= params_.max_gated && consistent) {
        ++stats_.resets;
        initialise();
      }
    } else {
      gated_in_a_row_ = 0;
    }
  }
  const double heading = heading_.update(x_.tail<2>());
  return kalman::tagTrackPose(t_, x_.head<2>(), p_.topLeftCorner<2, 2>(),
                              epoch.front().measurement.tag_on_robot, heading);
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
  if (!kalman::inGate(inn, uwb::ChiSquareGate(params_.gate))) {
    countRejection("kf_innovation_gate");
    return false;
  }
  kalman::josephUpdate<4, 2>(x_, p_, inn, h, fix.covariance);
  return true;
}

}  // namespace uwbloc::loc
