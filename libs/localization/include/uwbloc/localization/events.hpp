// The event stream every estimator consumes: our own plain types, time-ordered.
// MRPT and file formats stop at the dataset adapter; nothing here knows about them.
#pragma once

#include <Eigen/Core>
#include <variant>
#include <vector>

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

/// Composes a pose with an increment expressed in its own frame (SE(2) oplus).
Eigen::Vector3d composePose(const Eigen::Vector3d& pose, const Eigen::Vector3d& delta);

/// The increment that takes `from` to `to`, in the frame of `from` (SE(2) inverse compose).
Eigen::Vector3d relativePose(const Eigen::Vector3d& from, const Eigen::Vector3d& to);

/// Wraps an angle to (-pi, pi].
double wrapAngle(double a);

}  // namespace uwbloc::loc
