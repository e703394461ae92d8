#include "uwbloc/localization/methods/multilateration_estimator.hpp"

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

MultilaterationEstimator::MultilaterationEstimator(MultilaterationSolver solver,
                                                   const MultilaterationParams& params,
                                                   const EstimatorContext& context)
    : EpochUwbEstimator(params.front, context, params.epoch_window, TagUse::kPrimary,
                        params.learning),
      solver_(solver),
      params_(params) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

std::optional<PoseEstimate> MultilaterationEstimator::onEpoch(
    const std::vector<AcceptedRange>& epoch) {
  const auto checked =
      epochFix(solver_, epoch, toPlanar(epoch, rangeSigma()), params_.continuity, params_.deskew);
  if (!checked) return std::nullopt;
  const uwb::Fix& fix = *checked;
  const double t = epochTime(epoch);
  if (last_tag_ && t > last_t_) heading_.update((fix.position - *last_tag_) / (t - last_t_));
  last_tag_ = fix.position;
  last_t_ = t;

  return kalman::tagTrackPose(t, fix.position, fix.covariance,
                              epoch.front().measurement.tag_on_robot, heading_.heading());
}

}  // namespace uwbloc::loc
