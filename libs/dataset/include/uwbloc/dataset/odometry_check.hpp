// The odometry against the track of the ranges' own fixes, with no reference.
//
// Odometry written in another convention than the one read (a heading that counts clockwise, a
// turn in degrees, a distance in millimetres) dead-reckons a path that no rigid motion lays on
// where the robot went, and every method that fuses it then ends worse than the ranges alone:
// the MRPT demo with its odometry's y and turn negated took graph-uwb-odom from 0.115 to 3.95 m
// and uwb-pf from 0.159 to 4.26 m, without a word. The ranges' own multilateration fixes show
// where the robot went, so the check needs no reference.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::data {

/// One way of reading the odometry's increments (dx, dy, dtheta): each multiplied by `scale`.
struct OdometryConvention {
  const char* option;  ///< its name for import csv's --odometry-convention
  const char* name;    ///< "as written", "with its y and turn negated (a heading that ...)", ...
  Eigen::Vector3d scale;
};
/// as-written, clockwise (y and turn negated), degrees (the turn), mm and cm (the distances).
const std::vector<OdometryConvention>& odometryConventions();

/// How far the odometry, read one way, departs from the fixes' track.
struct OdometryReading {
  const OdometryConvention* convention = nullptr;
  std::vector<double> per_window;  ///< each window's median distance from the fixes [m]
};

/// The odometry read each way (`candidates`: its increments read in each of
/// odometryConventions(), in that order), dead-reckoned and laid on the fixes of `events`' ranges
/// (one tag's ranges within 0.1 s, three anchors or more, Gauss-Newton in the plane; at most
/// about 5 000, evenly spread) by the rigid motion that fits them best (2D Procrustes) in windows
/// of 30 s that hold 10 fixes or more spread over 1 m or more (the fit trimmed of fixes far off:
/// to the nearer half, then to those within three times the median distance, 0.3 m at least);
/// each window scored by its fixes' median distance from the path so laid. All readings, as
/// written first, over the same windows; nothing with under 20 increments or 4 such windows.
std::optional<std::vector<OdometryReading>> odometryReadings(
    const std::vector<std::vector<loc::OdometryIncrement>>& candidates,
    const std::vector<loc::Event>& events, const std::vector<uwb::Anchor>& anchors);
/// The same, the candidates being `events`' own increments multiplied by each convention's scale.
std::optional<std::vector<OdometryReading>> odometryReadings(
    const std::vector<loc::Event>& events, const std::vector<uwb::Anchor>& anchors);

/// Another reading of the odometry that follows the fixes where the one as written does not.
struct BetterReading {
  OdometryReading reading;
  int wins = 0, losses = 0;  ///< windows where it lies under half as far as written, and over
  size_t windows = 0;
  double median = 0.0, median_written = 0.0;  ///< over the windows [m]
  /// The sentence that says so.
  std::string describe() const;
};

/// Among `readings` (as written first), the one that lies under half as far from the fixes as the
/// odometry as written (and 0.1 m nearer) in the most windows, when those are 4 or more and at
/// least three times as many as the windows where it is the other way round; nothing otherwise.
/// (Windows of poor fixes, an NLOS stretch, fit every reading alike and count for neither.)
std::optional<BetterReading> betterOdometryReading(const std::vector<OdometryReading>& readings);

/// betterOdometryReading's sentence, with what it costs the methods that fuse the odometry.
std::optional<std::string> odometryTrackWarning(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors);

}  // namespace uwbloc::data
