#include "uwbloc/localization/methods/fix_filter.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc {

std::optional<uwb::Fix> FixFilter::primaryFix(const std::vector<AcceptedRange>& epoch, double t,
                                              Eigen::Vector3d* lever) {
  if (!readsEveryTag()) {
    *lever = epoch.front().measurement.tag_on_robot;
    return epochFix(fix_.solver, epoch, toPlanar(epoch, rangeSigma()), fix_.continuity,
                    fix_.deskew);
  }
  const TagsEpoch tags = tagsEpoch(fix_.solver, epoch, fix_.continuity, fix_.deskew);
  if (tags.fit) heading_track_.update(t, tags.fit->pose.z(), tags.fit->covariance(2, 2));
  *lever = tags.primary_lever;
  return tags.primary;
}

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
  Eigen::Vector3d lever = Eigen::Vector3d::Zero();
  const auto checked = primaryFix(epoch, t, &lever);
  if (!checked) return std::nullopt;
  const uwb::Fix& fix = *checked;
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
