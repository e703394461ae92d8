#include "uwbloc/localization/methods/uwb_akf.hpp"

#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc {

UwbAkf::UwbAkf(const UwbAkfParams& params, const EstimatorContext& context)
    : UwbKf(params.kf, context), akf_(params) {}

void UwbAkf::start(const uwb::Fix& fix) {
  UwbKf::start(fix);
  noise_ = {};
  noise_.R = fix.covariance;
  noise_started_ = false;  // Q̂_0 waits for the first interval
}

bool UwbAkf::predictAndUpdate(const uwb::Fix& fix, double dt) {
  Eigen::Matrix4d f, q;
  constantVelocityModel(dt, params_.accel_psd, f, q, params_.velocity_tau);
  if (!noise_started_) {
    noise_.Q = q;
    noise_started_ = true;
  }
  Eigen::Matrix<double, 2, 4> h = Eigen::Matrix<double, 2, 4>::Zero();
  h.leftCols<2>().setIdentity();
  const auto step = kalman::sageHusaStep<4, 2>(x_, p_, noise_, f, fix.position, h, akf_.forgetting,
                                               akf_.gamma, akf_.r_floor);
  if (step.diverged) ++stats_.events["divergence_inflated"];
  if (step.r_projected) ++stats_.events["r_kept_positive"];
  if (step.q_projected) ++stats_.events["q_kept_positive"];
  return true;
}

}  // namespace uwbloc::loc
