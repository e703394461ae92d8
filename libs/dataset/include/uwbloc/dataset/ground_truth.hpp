// Ground-truth trajectories: readers for the formats datasets ship.
#pragma once

#include <Eigen/Core>
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

/// Writes "t x y z qx qy qz qw" rows (TUM), z = 0.
std::string formatTum(const std::vector<TimedPose>& poses);

}  // namespace uwbloc::data
