#include "uwbloc/localization/estimator.hpp"

#include <algorithm>
#include <cmath>

namespace uwbloc::loc {

void sortByTime(std::vector<Event>& events) {
  std::stable_sort(events.begin(), events.end(),
                   [](const Event& a, const Event& b) { return eventTime(a) < eventTime(b); });
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

void rejectRange(EstimatorStatistics& stats, const uwb::Range& range, const std::string& reason) {
  countRejection(stats, reason, range.anchor_id);
  stats.range_rejections.push_back({range.t, range.anchor_id, range.tag_id, range.range, reason});
}

void Estimator::countRejection(const std::string& reason, int anchor_id) {
  loc::countRejection(stats_, reason, anchor_id);
}

}  // namespace uwbloc::loc
