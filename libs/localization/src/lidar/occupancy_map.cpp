#include "uwbloc/localization/lidar/occupancy_map.hpp"

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/serialization/CArchive.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "mrpt_grid.hpp"

namespace uwbloc::loc {

namespace {
constexpr float kOccupiedBelow = 0.5f;  // MRPT cells hold P(free): below this is occupied

bool endsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}
}  // namespace

OccupancyMap::OccupancyMap() : grid_(std::make_unique<Grid>()) {}
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

OccupancyMap OccupancyMap::blank(const Rect& area, double resolution, float p_free) {
  OccupancyMap map;
  map.grid_->setSize(static_cast<float>(area.xmin), static_cast<float>(area.xmax),
                     static_cast<float>(area.ymin), static_cast<float>(area.ymax),
                     static_cast<float>(resolution), p_free);
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
  // Sample the segment at a quarter cell: no occupied cell the segment crosses is missed. Only
  // the part inside the map is walked (outside counts as free), so the walk is bounded by the
  // map's size whatever the end points are.
  const Eigen::Vector2d d = b - a;
  const double len = d.norm();
  if (!std::isfinite(len)) return false;
  const double stop = len - skip_end;
  if (stop < 0.0 || len < 1e-12) return occupied(a);
  const Rect box = bounds();
  double s0 = 0.0, s1 = stop;  // the span of s (distance along a->b) inside the map
  for (int axis = 0; axis < 2; ++axis) {
    const double lo = axis == 0 ? box.xmin : box.ymin, hi = axis == 0 ? box.xmax : box.ymax;
    const double p = a(axis), v = d(axis) / len;
    if (std::abs(v) < 1e-15) {
      if (p < lo || p > hi) return false;
      continue;
    }
    double e0 = (lo - p) / v, e1 = (hi - p) / v;
    if (e0 > e1) std::swap(e0, e1);
    s0 = std::max(s0, e0);
    s1 = std::min(s1, e1);
  }
  const double step = 0.25 * resolution();
  for (double s = std::max(0.0, s0); s <= s1; s += step)
    if (occupied(a + d * (s / len))) return true;
  return false;
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

int OccupancyMap::sizeX() const { return static_cast<int>(grid_->getSizeX()); }
int OccupancyMap::sizeY() const { return static_cast<int>(grid_->getSizeY()); }
float OccupancyMap::freeProbability(int cx, int cy) const { return grid_->getCell(cx, cy); }
void OccupancyMap::setFreeProbability(int cx, int cy, float p_free) {
  grid_->setCell(cx, cy, p_free);
}
Eigen::Vector2d OccupancyMap::cellCentre(int cx, int cy) const {
  return {grid_->idx2x(cx), grid_->idx2y(cy)};
}

}  // namespace uwbloc::loc
