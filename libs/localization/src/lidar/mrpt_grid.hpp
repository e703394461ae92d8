// Internal MRPT adapter: the MRPT grid behind an OccupancyMap, for this library's and the
// simulator's MRPT code (scan insertion, ray casting). Not installed: no public header shows an
// MRPT type.
#pragma once

#include <mrpt/maps/COccupancyGridMap2D.h>

#include "uwbloc/localization/lidar/occupancy_map.hpp"

namespace uwbloc::loc {

struct OccupancyMap::Grid : mrpt::maps::COccupancyGridMap2D {};

struct MrptGridAccess {
  static mrpt::maps::COccupancyGridMap2D& grid(OccupancyMap& map) { return *map.grid_; }
  static const mrpt::maps::COccupancyGridMap2D& grid(const OccupancyMap& map) { return *map.grid_; }
};

}  // namespace uwbloc::loc
