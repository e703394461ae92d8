#include "uwbloc/localization/lidar/occupancy_map.hpp"

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/serialization/CArchive.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace uwbloc::loc {

namespace {
constexpr float kOccupiedBelow = 0.5f;  // MRPT cells hold P(free): below this is occupied

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}
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

OccupancyMap::OccupancyMap() : grid_(std::make_unique<mrpt::maps::COccupancyGridMap2D>()) {}
OccupancyMap::~OccupancyMap() = default;
OccupancyMap::OccupancyMap(OccupancyMap&&) noexcept = default;
OccupancyMap& OccupancyMap::operator=(OccupancyMap&&) noexcept = default;

OccupancyMap OccupancyMap::load(const std::string& path, double resolution,
                                const Eigen::Vector2d& origin) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw std::runtime_error(path + ": map not found");
  OccupancyMap map;
  bool ok = false;
  if (endsWith(path, ".gridmap") || endsWith(path, ".gridmap.gz")) {
    try {
      mrpt::io::CFileGZInputStream in(path);
      mrpt::serialization::archiveFrom(in) >> *map.grid_;
      ok = true;
    } catch (const std::exception&) {
      ok = false;
    }
  } else if (endsWith(path, ".yaml") || endsWith(path, ".yml")) {
    ok = map.grid_->loadFromROSMapServerYAML(path);
  } else {
    // The image's bottom-left pixel sits at `origin`; MRPT wants the pixel of the map origin.
    const mrpt::math::TPoint2D pixel(-origin.x() / resolution, -origin.y() / resolution);
    ok = map.grid_->loadFromBitmapFile(path, static_cast<float>(resolution), pixel);
  }
  if (!ok || map.grid_->getSizeX() == 0) throw std::runtime_error(path + ": cannot read map");
  return map;
}

OccupancyMap OccupancyMap::fromRectangles(const Rect& bounds, const std::vector<Rect>& obstacles,
                                          double resolution, bool walls) {
  OccupancyMap map;
  const double margin = walls ? resolution : 0.0;
  map.grid_->setSize(
      static_cast<float>(bounds.xmin - margin), static_cast<float>(bounds.xmax + margin),
      static_cast<float>(bounds.ymin - margin), static_cast<float>(bounds.ymax + margin),
      static_cast<float>(resolution), 1.0f);
  auto& g = *map.grid_;
  const int nx = static_cast<int>(g.getSizeX()), ny = static_cast<int>(g.getSizeY());
  for (int cy = 0; cy < ny; ++cy)
    for (int cx = 0; cx < nx; ++cx) {
      const double x = g.idx2x(cx), y = g.idx2y(cy);
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
      g.setCell(cx, cy, occ ? 0.0f : 1.0f);
    }
  return map;
}

OccupancyMap OccupancyMap::fromScans(const std::vector<const LaserScan*>& scans,
                                     const std::vector<Eigen::Vector3d>& poses, double resolution) {
  OccupancyMap map;
  map.grid_->setSize(-10, 10, -10, 10, static_cast<float>(resolution), 0.5f);  // grows as needed
  for (size_t i = 0; i < scans.size() && i < poses.size(); ++i) {
    const LaserScan& s = *scans[i];
    mrpt::obs::CObservation2DRangeScan obs;
    const size_t n = s.ranges.size();
    obs.resizeScan(n);
    obs.rightToLeft = s.angle_increment >= 0.0f;
    obs.aperture = std::abs(s.angle_increment) * static_cast<float>(n > 1 ? n - 1 : 1);
    obs.maxRange = s.max_range;
    obs.sensorPose = mrpt::poses::CPose3D(s.sensor_pose.x(), s.sensor_pose.y(), s.sensor_height,
                                          s.sensor_pose.z(), 0, 0);
    for (size_t k = 0; k < n; ++k) {
      obs.setScanRange(k, s.ranges[k]);
      obs.setScanRangeValidity(k, s.valid[k] != 0);
    }
    const mrpt::poses::CPose3D pose(poses[i].x(), poses[i].y(), 0.0, poses[i].z(), 0, 0);
    map.grid_->insertObservation(obs, pose);
  }
  return map;
}

void OccupancyMap::save(const std::string& path) const {
  mrpt::io::CFileGZOutputStream out(path);
  mrpt::serialization::archiveFrom(out) << *grid_;
}

bool OccupancyMap::inside(const Eigen::Vector2d& p) const {
  const auto& g = *grid_;
  return p.x() >= g.getXMin() && p.x() < g.getXMax() && p.y() >= g.getYMin() && p.y() < g.getYMax();
}

bool OccupancyMap::occupied(const Eigen::Vector2d& p) const {
  if (!inside(p)) return false;
  return grid_->getPos(static_cast<float>(p.x()), static_cast<float>(p.y())) < kOccupiedBelow;
}

bool OccupancyMap::segmentBlocked(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                  double skip_end) const {
  // Sample the segment at a quarter cell: no occupied cell the segment crosses is missed.
  const Eigen::Vector2d d = b - a;
  const double len = d.norm();
  const double step = 0.25 * resolution();
  const double stop = len - skip_end;
  for (double s = 0.0; s <= stop; s += step)
    if (occupied(a + d * (s / std::max(len, 1e-12)))) return true;
  return false;
}

LaserScan OccupancyMap::castScan(const Eigen::Vector3d& robot_pose,
                                 const LidarParams& lidar) const {
  mrpt::obs::CObservation2DRangeScan obs;
  obs.aperture = static_cast<float>(lidar.fov);
  obs.maxRange = static_cast<float>(lidar.max_range);
  obs.rightToLeft = true;
  obs.sensorPose = mrpt::poses::CPose3D(lidar.sensor_pose.x(), lidar.sensor_pose.y(),
                                        lidar.sensor_height, lidar.sensor_pose.z(), 0, 0);
  grid_->laserScanSimulator(obs,
                            mrpt::poses::CPose2D(robot_pose.x(), robot_pose.y(), robot_pose.z()),
                            kOccupiedBelow, static_cast<size_t>(lidar.rays), 0.0f);
  LaserScan scan;
  scan.sensor_pose = lidar.sensor_pose;
  scan.sensor_height = lidar.sensor_height;
  scan.max_range = static_cast<float>(lidar.max_range);
  const size_t n = obs.getScanSize();
  // MRPT spaces the rays by aperture / (N - 1) from -aperture/2 (so a full circle repeats its
  // first direction in the last ray).
  scan.angle_increment = static_cast<float>(n > 1 ? lidar.fov / static_cast<double>(n - 1) : 0.0);
  scan.angle_min = static_cast<float>(-lidar.fov / 2);
  scan.ranges.resize(n);
  scan.valid.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const float r = obs.getScanRange(i);
    scan.ranges[i] = r;
    scan.valid[i] = obs.getScanRangeValidity(i) && r >= lidar.min_range && r < lidar.max_range;
  }
  return scan;
}

std::vector<Eigen::Vector2d> OccupancyMap::freeCells() const {
  std::vector<Eigen::Vector2d> out;
  const auto& g = *grid_;
  for (unsigned cy = 0; cy < g.getSizeY(); ++cy)
    for (unsigned cx = 0; cx < g.getSizeX(); ++cx)
      if (g.getCell(static_cast<int>(cx), static_cast<int>(cy)) > 0.6f)
        out.emplace_back(g.idx2x(cx), g.idx2y(cy));
  return out;
}

Rect OccupancyMap::bounds() const {
  return {grid_->getXMin(), grid_->getYMin(), grid_->getXMax(), grid_->getYMax()};
}

double OccupancyMap::resolution() const { return grid_->getResolution(); }

}  // namespace uwbloc::loc
