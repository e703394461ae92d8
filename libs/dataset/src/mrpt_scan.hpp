// Internal MRPT adapter: the one conversion of a planar scan in each direction, shared by the
// rawlog reader and writer and the world builder.
#pragma once

#include <mrpt/obs/CObservation2DRangeScan.h>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::data {

/// MRPT's scan as ours (time, sensor pose and height, ray geometry, ranges and validity).
loc::LaserScan fromMrpt(const mrpt::obs::CObservation2DRangeScan& obs, double t);

/// Our scan as MRPT's (the timestamp and label are the caller's).
mrpt::obs::CObservation2DRangeScan toMrpt(const loc::LaserScan& scan);

}  // namespace uwbloc::data
