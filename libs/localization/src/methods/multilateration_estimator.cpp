#include "uwbloc/localization/methods/multilateration_estimator.hpp"

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

MultilaterationEstimator::MultilaterationEstimator(MultilaterationSolver solver,
                                                   const MultilaterationParams& params,
                                                   const EstimatorContext& context)
    : EpochUwbEstimator(params.front, context, params.epoch_window, tagUse(params.tags, context),
                        params.learning),
      solver_(solver),
      params_(params) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

std::optional<PoseEstimate> MultilaterationEstimator::onEpoch(
    const std::vector<AcceptedRange>& epoch) {
  const double t = epochTime(epoch);
  const TagsEpoch tags = tagsEpoch(solver_, epoch, params_.continuity, params_.deskew);
  if (tags.fit) {
    // The pose and heading of the fit; a later epoch of the primary tag alone keeps the heading.
    heading_.setHeading(tags.fit->pose.z());
    last_tag_ = tags.primary->position;
    last_t_ = t;
    PoseEstimate e;
    e.t = t;
    e.pose = tags.fit->pose;
    e.covariance = tags.fit->covariance;
    e.heading_valid = true;
    return e;
  }
  if (!tags.primary) return std::nullopt;
  const uwb::Fix& fix = *tags.primary;
  if (last_tag_ && t > last_t_) heading_.update((fix.position - *last_tag_) / (t - last_t_));
  last_tag_ = fix.position;
  last_t_ = t;
  return kalman::tagTrackPose(t, fix.position, fix.covariance, tags.primary_lever,
                              heading_.heading());
}

}  // namespace uwbloc::loc
