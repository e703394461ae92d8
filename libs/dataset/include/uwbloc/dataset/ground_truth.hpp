// Ground-truth trajectories: readers for the formats datasets ship.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/dataset/manifest.hpp"

namespace uwbloc::data {

struct TimedPose {
  double t = 0.0;
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();  ///< (x, y, theta)
};

/// The heading (the rotation about z) of each quaternion (qx qy qz qw as TUM writes them) of the
/// file `path`. A planar robot's quaternion hardly tilts the vertical: when, read so, the median
/// one tilts it over 45 deg and, read as "qw qx qy qz" (the scalar first, as several libraries
/// write it), under 15 deg, they are read that way; either case, and a tilt that neither reading
/// explains, adds a sentence naming `path` to `warnings` (when given).
std::vector<double> planarHeadings(const std::vector<Eigen::Vector4d>& quaternions,
                                   const std::string& path, std::vector<std::string>* warnings);

/// Headings written in degrees, read as such: a heading turns as the direction of travel does
/// (forward or backwards, and whatever constant angle a body frame turned on the robot keeps),
/// which headings in degrees read as radians do not. Between successive stretches of 0.1 m or
/// more (successive poses within 5 s), the turn of the course is compared with the turn of the
/// heading read as radians and as degrees; where the two readings differ by 5 deg or more and
/// 20 such turns or more tell, with 80 % of them closer in degrees, every heading of `poses` is
/// turned into radians and a sentence naming `path` added to `warnings` (when given). Driving
/// straight tells nothing.
void headingsInRadians(std::vector<TimedPose>& poses, const std::string& path,
                       std::vector<std::string>* warnings);

/// Reads a ground-truth file. `step_times` maps step k of a "step x y phi" file to the time of
/// the rawlog's step k. Rows must be in time order. Throws InputError naming file and line.
/// A TUM file's headings are planarHeadings' (with `warnings`); another's are read by
/// headingsInRadians.
std::vector<TimedPose> readGroundTruth(const std::string& path, GroundTruthFormat format,
                                       const std::vector<double>& step_times = {},
                                       std::vector<std::string>* warnings = nullptr);

/// Ground truth at time t, linearly interpolated (heading along the shorter arc). Nothing when
/// t is outside the ground truth (or not a number) or the bracketing samples are more than
/// `max_gap` apart.
std::optional<Eigen::Vector3d> interpolateGroundTruth(const std::vector<TimedPose>& gt, double t,
                                                      double max_gap);

/// Writes "t x y z qx qy qz qw" rows (TUM), z = 0.
std::string formatTum(const std::vector<TimedPose>& poses);

}  // namespace uwbloc::data
