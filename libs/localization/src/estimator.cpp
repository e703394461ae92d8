#include "uwbloc/localization/estimator.hpp"

#include <cmath>

namespace uwbloc::loc {

Eigen::Vector3d composePose(const Eigen::Vector3d& pose, const Eigen::Vector3d& delta) {
  const double c = std::cos(pose.z()), s = std::sin(pose.z());
  return {pose.x() + c * delta.x() - s * delta.y(), pose.y() + s * delta.x() + c * delta.y(),
          wrapAngle(pose.z() + delta.z())};
}

Eigen::Vector3d relativePose(const Eigen::Vector3d& from, const Eigen::Vector3d& to) {
  const double c = std::cos(from.z()), s = std::sin(from.z());
  const Eigen::Vector2d d = to.head<2>() - from.head<2>();
  return {c * d.x() + s * d.y(), -s * d.x() + c * d.y(), wrapAngle(to.z() - from.z())};
}

double wrapAngle(double a) {
  a = std::fmod(a + M_PI, 2.0 * M_PI);
  if (a <= 0.0) a += 2.0 * M_PI;
  return a - M_PI;
}

std::optional<PoseEstimate> Estimator::process(const Event& event) {
  return guard(doProcess(event));
}

std::optional<PoseEstimate> Estimator::finish() { return guard(doFinish()); }

std::vector<PoseEstimate> Estimator::finishAll() {
  std::vector<PoseEstimate> out;
  for (auto& e : doFinishAll())
    if (auto ok = guard(e)) out.push_back(*ok);
  return out;
}

std::optional<PoseEstimate> Estimator::guard(std::optional<PoseEstimate> estimate) {
  if (!estimate) return estimate;
  if (estimate->pose.allFinite() && estimate->covariance.allFinite() && std::isfinite(estimate->t))
    return estimate;
  countRejection("non_finite_estimate");
  ++stats_.resets;
  reset();
  return std::nullopt;
}

void Estimator::countRejection(uwb::RejectReason reason, int anchor_id) {
  countRejection(uwb::toString(reason), anchor_id);
}

void countRejection(EstimatorStatistics& stats, const std::string& reason, int anchor_id) {
  ++stats.rejected[reason];
  if (anchor_id >= 0) ++stats.rejected_by_anchor[anchor_id][reason];
}

void Estimator::countRejection(const std::string& reason, int anchor_id) {
  loc::countRejection(stats_, reason, anchor_id);
}

}  // namespace uwbloc::loc
