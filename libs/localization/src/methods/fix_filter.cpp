#include "uwbloc/localization/methods/fix_filter.hpp"

#include <algorithm>

namespace uwbloc::loc {

std::optional<PoseEstimate> FixFilter::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const auto checked =
      epochFix(fix_.solver, epoch, toPlanar(epoch, rangeSigma()), fix_.continuity, fix_.deskew);
  if (!checked) return std::nullopt;
  const uwb::Fix& fix = *checked;
  const double t = epochTime(epoch);
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
  return pose(t_, epoch.front().measurement.tag_on_robot);
}

}  // namespace uwbloc::loc
