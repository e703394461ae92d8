#include "uwbloc/localization/methods/odometry_estimator.hpp"

namespace uwbloc::loc {

OdometryEstimator::OdometryEstimator(const OdometryParams& params, const EstimatorContext& context)
    : pose_(context.initial_pose.value_or(Eigen::Vector3d::Zero())), start_t_(context.startTime()) {
  pose_.z() = wrapAngle(pose_.z() + params.heading_offset);
}

std::optional<PoseEstimate> OdometryEstimator::doProcess(const Event& event) {
  const auto* odo = std::get_if<OdometryIncrement>(&event);
  if (!odo) return std::nullopt;
  if (!odo->delta.allFinite()) {
    countRejection("non_finite_odometry");
    return std::nullopt;
  }
  if (odo->t <= start_t_) {
    countRejection("odometry_before_start");
    return std::nullopt;
  }
  pose_ = composePose(pose_, odo->delta);
  PoseEstimate est;
  est.t = odo->t;
  est.pose = pose_;
  return est;
}

}  // namespace uwbloc::loc
