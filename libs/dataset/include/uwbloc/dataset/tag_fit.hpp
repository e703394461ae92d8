// Where a tag sits on the robot, read from the ranges against a reference of the robot's pose.
//
// A reference (motion capture, a total station, a SLAM solution) gives the robot's pose, not the
// tag's. The tag's place on the robot (its lever arm, and its height) decides every true range,
// and a wrong one reads as a range error that swings with the heading and the distance. The fit
// below takes the tag position that makes the ranges agree best with the reference: the least
// median |error - its anchor's median error| (each anchor's median error is a constant bias, an
// antenna delay, and no evidence about the tag), searched on a 5 cm grid, lever arm within 1 m
// of the start, height within the anchors' span widened by 1 m. The median makes NLOS ranges
// and outliers weigh nothing as long as they are fewer than half.
#pragma once

#include <Eigen/Core>
#include <map>
#include <vector>

namespace uwbloc::data {

/// One range beside the reference pose at its time.
struct TagFitSample {
  Eigen::Vector3d pose;    ///< the robot's reference pose (x, y, yaw)
  Eigen::Vector3d anchor;  ///< the anchor's position
  double range = 0.0;      ///< the measured range [m]
  int anchor_id = 0;
};

struct TagFit {
  Eigen::Vector3d tag = Eigen::Vector3d::Zero();  ///< on the robot (x, y, z) [m]
  double deviation = 0.0;      ///< median |error - its anchor's median error| there [m]
  std::map<int, double> bias;  ///< anchor id -> median range error there [m]
};

/// |error - its anchor's median error| of every sample with the tag at `tag` on the robot; each
/// anchor's median error into `bias` when given.
std::vector<double> rangeDeviations(const std::vector<TagFitSample>& samples,
                                    const Eigen::Vector3d& tag,
                                    std::map<int, double>* bias = nullptr);

/// The fit from `start`: the lever arm (x, y) when `fit_lever` (the reference must carry the
/// heading), the height when `fit_height`; the rest stays as in `start`. Uses at most 2000
/// samples, evenly spread, for the search, and all of them for the result's deviation and
/// biases. Needs at least 50 samples; fewer give `start` back with its own deviation.
TagFit fitTagOnRobot(const std::vector<TagFitSample>& samples, const Eigen::Vector3d& start,
                     bool fit_lever, bool fit_height);

}  // namespace uwbloc::data
