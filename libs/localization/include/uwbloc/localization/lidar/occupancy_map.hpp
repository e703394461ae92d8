// A 2D occupancy grid (MRPT's COccupancyGridMap2D behind a small interface): loading, saving,
// cell access and segment occlusion tests. Building worlds and ray-casting scans belong to the
// simulator (libs/dataset/world.hpp).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::loc {

/// Axis-aligned rectangle [xmin, xmax] x [ymin, ymax] in metres.
struct Rect {
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
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
  /// A grid over `area` with square cells of `resolution`, every cell holding P(free) `p_free`.
  static OccupancyMap blank(const Rect& area, double resolution, float p_free);

  /// Saves as ".gridmap.gz" (MRPT serialisation).
  void save(const std::string& path) const;

  bool inside(const Eigen::Vector2d& p) const;
  bool occupied(const Eigen::Vector2d& p) const;  ///< outside the map counts as free
  /// True when the segment a-b crosses an occupied cell, ignoring `skip_end` metres at b (an
  /// anchor mounted on a wall would otherwise block every segment).
  bool segmentBlocked(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                      double skip_end = 0.0) const;
  /// Centres of the free cells (P(free) above 0.6), for global initialisation.
  std::vector<Eigen::Vector2d> freeCells() const;
  Rect bounds() const;
  double resolution() const;

  /// Cells: (cx, cy) from the bottom-left, cx < sizeX(), cy < sizeY().
  int sizeX() const;
  int sizeY() const;
  float freeProbability(int cx, int cy) const;
  void setFreeProbability(int cx, int cy, float p_free);
  Eigen::Vector2d cellCentre(int cx, int cy) const;

 private:
  friend struct MrptGridAccess;  // the MRPT adapters of this library and the simulator
  struct Grid;                   // the MRPT grid (lidar/mrpt_grid.hpp)
  std::unique_ptr<Grid> grid_;
};

}  // namespace uwbloc::loc
