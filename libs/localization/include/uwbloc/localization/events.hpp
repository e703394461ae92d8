// The event stream every estimator consumes: our own plain types, time-ordered.
// MRPT and file formats stop at the dataset adapter; nothing here knows about them.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <variant>
#include <vector>

#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::loc {

/// Odometry increment: the motion since the previous increment, in the frame of the robot at
/// the start of the motion (dx forward, dy left, dtheta) [m, m, rad].
struct OdometryIncrement {
  double t = 0.0;
  Eigen::Vector3d delta = Eigen::Vector3d::Zero();
};

/// One planar LiDAR scan.
struct LaserScan {
  double t = 0.0;
  Eigen::Vector3d sensor_pose = Eigen::Vector3d::Zero();  ///< (x, y, yaw) on the robot
  double sensor_height = 0.0;                             ///< [m]
  float angle_min = 0.0f;                                 ///< angle of the first ray [rad]
  float angle_increment = 0.0f;                           ///< [rad]
  float max_range = 0.0f;                                 ///< [m]
  std::vector<float> ranges;                              ///< [m]
  std::vector<unsigned char> valid;                       ///< 1 where the ray returned
};

/// Planar IMU sample.
struct ImuSample {
  double t = 0.0;
  Eigen::Vector2d accel = Eigen::Vector2d::Zero();  ///< body-frame acceleration [m/s^2]
  double gyro_z = 0.0;                              ///< yaw rate [rad/s]
};

using Event = std::variant<uwb::Range, OdometryIncrement, LaserScan, ImuSample>;

inline double eventTime(const Event& e) {
  return std::visit([](const auto& v) { return v.t; }, e);
}

using uwbloc::composePose;
using uwbloc::relativePose;
using uwbloc::wrapAngle;

/// Stable time order of an event stream: the one ordering every reader, importer and the
/// simulator use (events with equal stamps keep the order they were produced in).
void sortByTime(std::vector<Event>& events);

/// Calls fn(i, endpoint) for every `step`-th ray i of `scan` that returned with a range in
/// [min_range, max_range), the endpoint in the robot frame (through the sensor's pose on it).
template <class Fn>
void forEachScanEndpoint(const LaserScan& scan, size_t step, double min_range, double max_range,
                         Fn&& fn) {
  for (size_t i = 0; i < scan.ranges.size(); i += step) {
    const double r = scan.ranges[i];
    if (!scan.valid[i] || r < min_range || r >= max_range) continue;
    const double a = scan.angle_min + static_cast<double>(i) * scan.angle_increment;
    fn(i, transformPoint(scan.sensor_pose, Eigen::Vector2d(r * std::cos(a), r * std::sin(a))));
  }
}

}  // namespace uwbloc::loc
