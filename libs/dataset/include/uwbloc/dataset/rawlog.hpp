// MRPT rawlog <-> our event stream. MRPT types stop here.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::data {

struct Recording {
  std::vector<loc::Event> events;  ///< time-ordered (stable sort by time)
  /// Time of rawlog step k, as MRPT's rawlog readers count steps: in the action/sensory-frame
  /// layout, the k-th action followed by a sensory frame (a leading frame with no action before
  /// it is not a step); in the observation-only layout, the k-th observation.
  std::vector<double> step_times;
  std::map<std::string, long> counts;  ///< objects read, per kind, and repaired timestamps
};

/// Reads both rawlog layouts (action + sensory frame pairs, and observations only). MRPT's
/// deserialiser runs in a child process (rawlog_sandbox.cpp): a rawlog that crashes it, or
/// makes it allocate beyond the memory budget, is an InputError naming the object and its byte
/// offset, never a crash of the caller.
///  - CObservationBeaconRanges -> uwb::Range (one per beacon; the sensor pose on the robot kept)
///  - CObservation2DRangeScan  -> loc::LaserScan
///  - CActionRobotMovement2D   -> loc::OdometryIncrement, stamped with the time of the sensory
///    frame that follows it (the motion is measured up to that frame)
///  - CObservationOdometry     -> loc::OdometryIncrement between consecutive readings
/// Observations with no timestamp take the time of their sensory frame (its first timestamped
/// observation). Throws InputError naming the file for a missing, truncated or corrupt rawlog.
Recording readRawlog(const std::string& path);

/// Where the reader is: objects read so far, and the byte offset (in the uncompressed stream) of
/// the object being read.
struct RawlogProgress {
  uint64_t objects = 0;
  uint64_t position = 0;
};

/// readRawlog's work, in the calling process: MRPT's deserialiser may crash on a corrupt stream
/// (a null pointer it dereferences). `progress`, when given, is updated before each object.
Recording readRawlogInProcess(const std::string& path, RawlogProgress* progress = nullptr);

/// Writes events as an observation-only rawlog (gzip-compressed): consecutive ranges with the
/// same timestamp become one CObservationBeaconRanges; odometry increments are accumulated into
/// CObservationOdometry poses; scans become CObservation2DRangeScan.
void writeRawlog(const std::string& path, const std::vector<loc::Event>& events);

}  // namespace uwbloc::data
