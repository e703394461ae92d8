// The kidnapped robot: a recording spliced so that, at `t_kidnap`, the robot is carried to where
// it was `skip` seconds later, with no odometry of the move. Ranges, scans and the reference
// after the splice are those of the later part, shifted back by `skip`.
#pragma once

#include <optional>
#include <variant>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/metrics.hpp"

namespace uwbloc::test {

inline data::Dataset kidnap(const data::Dataset& ds, double t_kidnap, double skip) {
  data::Dataset out = ds;
  out.events.clear();
  out.ground_truth.clear();
  for (const auto& e : ds.events) {
    const double t = loc::eventTime(e);
    if (t < t_kidnap) {
      out.events.push_back(e);
    } else if (t >= t_kidnap + skip) {
      loc::Event shifted = e;
      std::visit([&](auto& m) { m.t -= skip; }, shifted);
      out.events.push_back(shifted);
    }
  }
  for (const auto& p : ds.ground_truth) {
    if (p.t < t_kidnap)
      out.ground_truth.push_back(p);
    else if (p.t >= t_kidnap + skip)
      out.ground_truth.push_back({p.t - skip, p.pose});
  }
  out.end_time = ds.end_time - skip;
  return out;
}

/// Seconds from the kidnapping until the error stays under `tolerance` for `hold` seconds;
/// nothing if it never does.
inline std::optional<double> recoveryTime(const data::Dataset& ds,
                                          const std::vector<loc::PoseEstimate>& trajectory,
                                          double t_kidnap, double tolerance, double hold) {
  bool within = false;  // the error has stayed under `tolerance` since `since`
  double since = 0.0;
  for (const auto& p : trajectory) {
    if (p.t < t_kidnap) continue;
    const auto gt = eval::interpolateGroundTruth(ds.ground_truth, p.t, 1.0);
    if (!gt) continue;
    if ((p.pose.head<2>() - gt->head<2>()).norm() > tolerance) {
      within = false;
      continue;
    }
    if (!within) since = p.t;
    within = true;
    if (p.t - since >= hold) return since - t_kidnap;
  }
  return std::nullopt;
}

}  // namespace uwbloc::test
