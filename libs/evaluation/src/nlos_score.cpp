#include "uwbloc/evaluation/nlos_score.hpp"

#include <cmath>

#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::eval {

NlosScores scoreNlos(const data::Dataset& ds, const std::vector<loc::RangeDecision>& decisions,
                     double bad_threshold, int anchor) {
  NlosScores out;
  // The tag's pose on the robot is the same for every range of a dataset.
  Eigen::Vector3d tag = Eigen::Vector3d::Zero();
  for (const auto& e : ds.events)
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      tag = r->tag_on_robot;
      break;
    }
  for (const auto& d : decisions) {
    const uwb::Anchor* a = uwb::findAnchor(ds.anchors, d.anchor_id);
    const auto truth = interpolateGroundTruth(ds.ground_truth, d.t, ds.manifest.gt_max_gap);
    if (!a || !truth) continue;
    const double err = std::abs(d.range - uwb::predictRange(*truth, tag, a->position));
    const bool bad = err > bad_threshold;
    if (bad && anchor >= 0 && d.anchor_id != anchor) continue;
    for (auto [score, flag] :
         {std::pair{&out.pose, d.flag_pose}, std::pair{&out.raycast, d.flag_raycast}}) {
      if (bad) {
        ++score->bad;
        score->bad_flagged += flag;
      } else {
        ++score->good;
        score->good_flagged += flag;
      }
    }
    if (std::isfinite(d.p_nlos)) {
      const bool flag = d.p_nlos > 0.5;
      (bad ? out.state.bad : out.state.good) += 1;
      (bad ? out.state.bad_flagged : out.state.good_flagged) += flag;
    }
  }
  return out;
}

}  // namespace uwbloc::eval
