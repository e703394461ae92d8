#include "uwbloc/localization/methods/fix_filter.hpp"

#include <algorithm>

namespace uwbloc::loc {

std::optional<PoseEstimate> FixFilter::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const uwb::Fix fix = multilaterate(fix_.solver, toPlanar(epoch, rangeSigma()));
  if (!fix.ok()) {
    countRejection(std::string("epoch_") + uwb::toString(fix.status));
    return std::nullopt;
  }
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
