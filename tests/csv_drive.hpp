// A recording as CSV text for the importer's tests: a robot driving a circle among four anchors.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::test {

// Four anchors at different heights as an anchors CSV, and a robot driving a 2.5 m circle among
// them at a varying rate, heading along it, 0.1 s apart for 30 s, with a tag at `tag` on it: the
// ranges as a CSV (each anchor's a bias of 0.05 m times its index, one range in eight 1.5 m long)
// and the reference as 't,x,y,theta' rows, moved by `frame` (the reference's frame seen from the
// anchors' is its inverse) and stamped `lag` [s] early (its clock behind the ranges'). With
// `one_at_a_time`, each step ranges to one anchor only, in turn.
constexpr const char* kFourAnchors = "1,-4,-4,0.4\n2,5,-4,2.2\n3,5,5,1.5\n4,-4,5,2.6\n";
inline std::pair<std::string, std::string> driveACircle(const Eigen::Vector3d& tag,
                                                        const Eigen::Vector3d& frame,
                                                        double lag = 0.0,
                                                        bool one_at_a_time = false) {
  const Eigen::Vector3d at[] = {{-4, -4, 0.4}, {5, -4, 2.2}, {5, 5, 1.5}, {-4, 5, 2.6}};
  std::string ranges = "t,anchor_id,range\n", ref = "t,x,y,theta\n";
  char buf[160];
  for (int k = 0; k < 300; ++k) {
    // Faster and slower in turn: on a circle at a steady rate a lag would be a rotation.
    const double t = 10.0 + 0.1 * k, a = 0.02 * k + 0.3 * std::sin(0.05 * k);
    const Eigen::Vector3d pose(2.5 * std::cos(a), 2.5 * std::sin(a), a + M_PI / 2);
    for (int i = 0; i < 4; ++i) {
      if (one_at_a_time && i != k % 4) continue;
      const double nlos = ((one_at_a_time ? k / 4 : k) + i) % 8 == 0 ? 1.5 : 0.0;
      const double r = (uwb::tagPosition(pose, tag) - at[i]).norm() + 0.05 * i + nlos;
      std::snprintf(buf, sizeof buf, "%.2f,%d,%.6f\n", t, i + 1, r);
      ranges += buf;
    }
    const Eigen::Vector3d moved = composePose(frame, pose);
    std::snprintf(buf, sizeof buf, "%.3f,%.6f,%.6f,%.6f\n", t - lag, moved.x(), moved.y(),
                  moved.z());
    ref += buf;
  }
  return {ranges, ref};
}

}  // namespace uwbloc::test
