#include "uwbloc/dataset/world.hpp"

#include <cmath>
#include <stdexcept>

#include "lidar/mrpt_grid.hpp"
#include "mrpt_scan.hpp"

namespace uwbloc::data {

namespace {
constexpr float kOccupiedBelow = 0.5f;  // MRPT cells hold P(free): below this is occupied
}  // namespace

LidarParams LidarParams::preset(const std::string& name) {
  LidarParams p;
  if (name == "rplidar_a2") {
    p.rays = 400;
    p.fov = 2 * M_PI;
    p.min_range = 0.2;
    p.max_range = 8.0;
    p.sigma = 0.01;
  } else if (name == "sick_lms") {
    p.rays = 361;
    p.fov = M_PI;
    p.min_range = 0.05;
    p.max_range = 30.0;
    p.sigma = 0.01;
  } else {
    throw std::runtime_error("unknown LiDAR preset '" + name + "' (known: rplidar_a2, sick_lms)");
  }
  return p;
}

loc::OccupancyMap mapFromRectangles(const loc::Rect& bounds,
                                    const std::vector<loc::Rect>& obstacles, double resolution,
                                    bool walls) {
  const double margin = walls ? resolution : 0.0;
  loc::OccupancyMap map = loc::OccupancyMap::blank(
      {bounds.xmin - margin, bounds.ymin - margin, bounds.xmax + margin, bounds.ymax + margin},
      resolution, 1.0f);
  for (int cy = 0; cy < map.sizeY(); ++cy)
    for (int cx = 0; cx < map.sizeX(); ++cx) {
      const Eigen::Vector2d c = map.cellCentre(cx, cy);
      const double x = c.x(), y = c.y();
      bool occ =
          walls && (x < bounds.xmin || x > bounds.xmax || y < bounds.ymin || y > bounds.ymax);
      for (const auto& r : obstacles)
        occ = occ || (x >= r.xmin && x <= r.xmax && y >= r.ymin && y <= r.ymax);
      // Thin obstacles (a 2 cm plate) must still mark the cell they pass through.
      if (!occ)
        for (const auto& r : obstacles) {
          const double h = resolution / 2;
          occ = occ || (x + h > r.xmin && x - h < r.xmax && y + h > r.ymin && y - h < r.ymax);
        }
      map.setFreeProbability(cx, cy, occ ? 0.0f : 1.0f);
    }
  return map;
}

loc::OccupancyMap mapFromScans(const std::vector<const loc::LaserScan*>& scans,
                               const std::vector<Eigen::Vector3d>& poses, double resolution) {
  loc::OccupancyMap map = loc::OccupancyMap::blank({-10, -10, 10, 10}, resolution, 0.5f);
  auto& grid = loc::MrptGridAccess::grid(map);  // grows as needed
  for (size_t i = 0; i < scans.size() && i < poses.size(); ++i) {
    const mrpt::poses::CPose3D pose(poses[i].x(), poses[i].y(), 0.0, poses[i].z(), 0, 0);
    grid.insertObservation(toMrpt(*scans[i]), pose);
  }
  return map;
}

loc::LaserScan castScan(const loc::OccupancyMap& map, const Eigen::Vector3d& robot_pose,
                        const LidarParams& lidar) {
  mrpt::obs::CObservation2DRangeScan obs;
  obs.aperture = static_cast<float>(lidar.fov);
  obs.maxRange = static_cast<float>(lidar.max_range);
  obs.rightToLeft = true;
  obs.sensorPose = mrpt::poses::CPose3D(lidar.sensor_pose.x(), lidar.sensor_pose.y(),
                                        lidar.sensor_height, lidar.sensor_pose.z(), 0, 0);
  loc::MrptGridAccess::grid(map).laserScanSimulator(
      obs, mrpt::poses::CPose2D(robot_pose.x(), robot_pose.y(), robot_pose.z()), kOccupiedBelow,
      static_cast<size_t>(lidar.rays), 0.0f);
  loc::LaserScan scan = fromMrpt(obs, 0.0);
  // The spacing from the model's own field of view, in double precision (MRPT's aperture is a
  // float).
  const size_t n = scan.ranges.size();
  scan.angle_increment = static_cast<float>(n > 1 ? lidar.fov / static_cast<double>(n - 1) : 0.0);
  for (size_t i = 0; i < scan.ranges.size(); ++i)
    scan.valid[i] =
        scan.valid[i] && scan.ranges[i] >= lidar.min_range && scan.ranges[i] < lidar.max_range;
  return scan;
}

}  // namespace uwbloc::data
