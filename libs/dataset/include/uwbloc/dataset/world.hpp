// Simulated worlds: occupancy grids built from rectangles or from scans taken at known poses,
// and noise-free LiDAR scans ray-cast on a grid. Only the simulator and `augment` need them.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/localization/lidar/occupancy_map.hpp"

namespace uwbloc::data {

/// LiDAR model used to ray-cast scans.
struct LidarParams {
  int rays = 360;          ///< beams per scan
  double fov = 2 * M_PI;   ///< field of view [rad], centred on the sensor's x axis
  double min_range = 0.2;  ///< returns closer than this are invalid [m]
  double max_range = 8.0;  ///< no return beyond this [m]
  double sigma = 0.01;     ///< range noise [m] (added by the caller)
  Eigen::Vector3d sensor_pose = Eigen::Vector3d::Zero();  ///< (x, y, yaw) on the robot
  double sensor_height = 0.2;                             ///< [m]
  /// Presets: "rplidar_a2" (0.2-8 m, 360 deg, 400 beams) and "sick_lms" (180 deg, 30 m, 361).
  static LidarParams preset(const std::string& name);
};

/// A free area `bounds` with occupied `obstacles`, and occupied walls around the border when
/// `walls` is set.
loc::OccupancyMap mapFromRectangles(const loc::Rect& bounds,
                                    const std::vector<loc::Rect>& obstacles, double resolution,
                                    bool walls = true);

/// Maps the scans taken at known poses (`poses[i]` for `scans[i]`) into a new grid.
loc::OccupancyMap mapFromScans(const std::vector<const loc::LaserScan*>& scans,
                               const std::vector<Eigen::Vector3d>& poses, double resolution);

/// Noise-free scan by ray casting on `map` from `robot_pose` (the caller adds noise). Rays
/// without a return inside the range limits are marked invalid.
loc::LaserScan castScan(const loc::OccupancyMap& map, const Eigen::Vector3d& robot_pose,
                        const LidarParams& lidar);

}  // namespace uwbloc::data
