// Internal MRPT adapter: the one conversion of a planar scan in each direction, shared by the
// rawlog reader and writer and the world builder.
#pragma once

#include <mrpt/obs/CObservation2DRangeScan.h>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::data {

/// A bool that MRPT deserialised as the byte it found: a corrupt rawlog may hold another value
/// than 0 or 1, which is undefined to load as bool, so the byte is read as what it is.
bool byteAsBool(const bool& flag);

/// MRPT's scan as ours (time, sensor pose and height, ray geometry, ranges and validity).
loc::LaserScan fromMrpt(const mrpt::obs::CObservation2DRangeScan& obs, double t);

/// Our scan as MRPT's (the timestamp and label are the caller's).
mrpt::obs::CObservation2DRangeScan toMrpt(const loc::LaserScan& scan);

}  // namespace uwbloc::data
