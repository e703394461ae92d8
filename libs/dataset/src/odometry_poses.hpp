// Odometry recorded as absolute poses (MRPT's CObservationOdometry, CARMEN's ODOM lines) turned
// into the increments of the event stream. Internal to the dataset library.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <optional>
#include <vector>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::data {

/// The motion of a robot driving at speed v [m/s] and yaw rate w [rad/s] for dt [s], in the
/// frame it started in: the arc (x, y) and the turn.
inline Eigen::Vector3d arcIncrement(double v, double w, double dt) {
  const double a = w * dt;
  if (std::abs(a) < 1e-9) return {v * dt, 0.0, a};
  return {v / w * std::sin(a), v / w * (1.0 - std::cos(a)), a};
}

class OdometryFromPoses {
 public:
  /// Appends the increment from the previous pose to `pose` (none for the first). A reading
  /// stamped before the previous one is not a later pose: it is refused (false) and changes
  /// nothing.
  bool add(double t, const Eigen::Vector3d& pose, std::vector<loc::Event>& events) {
    if (last_ && t < last_t_) return false;
    if (last_) {
      loc::OdometryIncrement inc;
      inc.t = t;
      inc.delta = loc::relativePose(*last_, pose);
      events.emplace_back(inc);
    }
    last_ = pose;
    last_t_ = t;
    return true;
  }

 private:
  std::optional<Eigen::Vector3d> last_;
  double last_t_ = 0.0;
};

}  // namespace uwbloc::data
