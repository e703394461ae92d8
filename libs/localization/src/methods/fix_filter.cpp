#include "uwbloc/localization/methods/fix_filter.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc {

void FixFilter::useTrackedHeading(PoseEstimate& e, const Eigen::Vector3d& lever) const {
  const auto heading = heading_track_.at(e.t);
  constexpr double kMaxStd = 30.0 * M_PI / 180.0;
  if (!heading || heading->second > kMaxStd * kMaxStd) return;
  const Eigen::Vector2d tag = tagFromRobot(e.pose, lever);
  const double theta = heading->first;
  // The position's covariance gains the lever arm's swing with the heading's variance.
  const Eigen::Vector2d swing = rotationDerivative(theta) * lever.head<2>();
  e.pose << robotFromTag(tag, lever, theta), theta;
  e.covariance.topLeftCorner<2, 2>() += heading->second * swing * swing.transpose();
  e.covariance(2, 2) = heading->second;
  e.heading_valid = true;
}

std::optional<PoseEstimate> FixFilter::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const double t = epochTime(epoch);
  // The primary tag's fix (from the tags' rigid fit, whose heading feeds the heading track, when
  // every tag is read).
  const TagsEpoch tags = tagsEpoch(fix_.solver, epoch, fix_.continuity, fix_.deskew);
  if (tags.fit) heading_track_.update(t, tags.fit->pose.z(), tags.fit->covariance(2, 2));
  if (!tags.primary) return std::nullopt;
  const uwb::Fix& fix = *tags.primary;
  const Eigen::Vector3d& lever = tags.primary_lever;
  const bool consistent = fix.residual_norm <= fix_.init_residual;
  auto initialise = [&] {
    start(fix);
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
    const double dt = std::max(0.0, t - t_);
    t_ = std::max(t_, t);
    if (predictAndUpdate(fix, dt)) {
      gated_in_a_row_ = 0;
    } else if (++gated_in_a_row_ >= fix_.max_gated && consistent) {
      ++stats_.resets;
      initialise();
    }
  }
  PoseEstimate e = pose(t_, lever);
  if (readsEveryTag()) useTrackedHeading(e, lever);
  return e;
}

}  // namespace uwbloc::loc
