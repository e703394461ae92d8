// A 2D occupancy grid (MRPT's COccupancyGridMap2D behind a small interface): loading, building
// from rectangles, segment occlusion tests and scan ray casting.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"

namespace mrpt::maps {
class COccupancyGridMap2D;
}

namespace uwbloc::loc {

/// Axis-aligned rectangle [xmin, xmax] x [ymin, ymax] in metres.
struct Rect {
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
};

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

class OccupancyMap {
 public:
  OccupancyMap();
  ~OccupancyMap();
  OccupancyMap(OccupancyMap&&) noexcept;
  OccupancyMap& operator=(OccupancyMap&&) noexcept;

  /// Loads a map: MRPT ".gridmap" / ".gridmap.gz", a ROS map_server ".yaml" (with its image),
  /// or an image (".png", ".pgm", ".bmp") with the given resolution and the map coordinates of
  /// the image's bottom-left corner. Throws std::runtime_error naming the file.
  static OccupancyMap load(const std::string& path, double resolution = 0.05,
                           const Eigen::Vector2d& origin = Eigen::Vector2d::Zero());
  /// A free area `bounds` with occupied `obstacles`, and occupied walls around the border when
  /// `walls` is set.
  static OccupancyMap fromRectangles(const Rect& bounds, const std::vector<Rect>& obstacles,
                                     double resolution, bool walls = true);

  /// Maps the scans taken at known poses (`poses[i]` for `scans[i]`) into a new grid.
  static OccupancyMap fromScans(const std::vector<const LaserScan*>& scans,
                                const std::vector<Eigen::Vector3d>& poses, double resolution);

  /// Saves as ".gridmap.gz" (MRPT serialisation).
  void save(const std::string& path) const;

  bool inside(const Eigen::Vector2d& p) const;
  bool occupied(const Eigen::Vector2d& p) const;  ///< outside the map counts as free
  /// True when the segment a-b crosses an occupied cell, ignoring `skip_end` metres at b (an
  /// anchor mounted on a wall would otherwise block every segment).
  bool segmentBlocked(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                      double skip_end = 0.0) const;
  /// Noise-free scan by ray casting from `robot_pose` (the caller adds noise). Rays without a
  /// return inside the range limits are marked invalid.
  LaserScan castScan(const Eigen::Vector3d& robot_pose, const LidarParams& lidar) const;

  /// Centres of the free cells (P(free) above 0.6), for global initialisation.
  std::vector<Eigen::Vector2d> freeCells() const;
  Rect bounds() const;
  double resolution() const;
  const mrpt::maps::COccupancyGridMap2D& grid() const { return *grid_; }

 private:
  std::unique_ptr<mrpt::maps::COccupancyGridMap2D> grid_;
};

}  // namespace uwbloc::loc
