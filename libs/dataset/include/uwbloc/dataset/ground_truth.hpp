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

/// Reads a ground-truth file. `step_times` maps step k of a "step x y phi" file to the time of
/// the rawlog's step k. Rows must be in time order. Throws InputError naming file and line.
std::vector<TimedPose> readGroundTruth(const std::string& path, GroundTruthFormat format,
                                       const std::vector<double>& step_times = {});

/// Ground truth at time t, linearly interpolated (heading along the shorter arc). Nothing when
/// t is outside the ground truth (or not a number) or the bracketing samples are more than
/// `max_gap` apart.
std::optional<Eigen::Vector3d> interpolateGroundTruth(const std::vector<TimedPose>& gt, double t,
                                                      double max_gap);

/// Writes "t x y z qx qy qz qw" rows (TUM), z = 0.
std::string formatTum(const std::vector<TimedPose>& poses);

}  // namespace uwbloc::data
