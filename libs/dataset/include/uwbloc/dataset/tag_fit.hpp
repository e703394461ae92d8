// Where a tag sits on the robot, read from the ranges against a reference of the robot's pose.
//
// A reference (motion capture, a total station, a SLAM solution) gives the robot's pose, not the
// tag's. The tag's place on the robot (its lever arm, and its height) decides every true range,
// and a wrong one reads as a range error that swings with the heading and the distance. The fit
// below takes the tag position that makes the ranges agree best with the reference: the least
// median |error - its link's median error| (each anchor-tag link's median error is a constant
// bias, an antenna delay, and no evidence about the tag), searched on a 5 cm grid, lever arm within
// 1 m of the start, height within the anchors' span widened by 1 m. The median makes NLOS ranges
// and outliers weigh nothing as long as they are fewer than half.
#pragma once

#include <Eigen/Core>
#include <map>
#include <utility>
#include <vector>

#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/localization/events.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::data {

/// One range beside the reference pose at its time.
struct TagFitSample {
  Eigen::Vector3d pose;    ///< the robot's reference pose (x, y, yaw)
  Eigen::Vector3d anchor;  ///< the anchor's position
  double range = 0.0;      ///< the measured range [m]
  int anchor_id = 0, tag_id = 0;
  Eigen::Vector3d tag_on_robot = Eigen::Vector3d::Zero();  ///< where the recording puts the tag
  double t = 0.0;                                          ///< the range's stamp [s]
  size_t event = 0;                                        ///< its index in the events
};
using Link = std::pair<int, int>;  ///< (anchor id, tag id)

/// A tag's range to a known anchor, as batchFixes reads it.
struct AnchorRange {
  double t = 0.0;
  int tag_id = 0, anchor_id = 0;
  Eigen::Vector3d anchor = Eigen::Vector3d::Zero();  ///< the anchor's position
  double range = 0.0;                                ///< [m]
  double tag_z = 0.0;                                ///< the tag's height [m]
};

/// Planar fixes from `ranges` (sorted by tag, then time): each batch of one tag's ranges within
/// 0.1 s of the batch's first, the latest range to each anchor projected to the tag's height,
/// three or more of them, solved by Gauss-Newton. Each fix with the index of its batch's last
/// range.
std::vector<std::pair<size_t, Eigen::Vector2d>> batchFixes(const std::vector<AnchorRange>& ranges);

/// The finite ranges from the robot's tags (on_robot) to known anchors that have a reference
/// pose `lag` [s] before their stamp (interpolated between poses at most `max_gap` [s] apart).
std::vector<TagFitSample> rangesBesideReference(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors,
                                                const std::vector<TimedPose>& reference,
                                                double lag = 0.0, double max_gap = 1.0);

/// |err_i - the median of its link's errors| for the samples' errors `err`; each link's median
/// into `median` when given.
std::vector<double> aboutLinkMedians(std::vector<double> err,
                                     const std::vector<TagFitSample>& samples,
                                     std::map<Link, double>* median = nullptr);

struct TagFit {
  Eigen::Vector3d tag = Eigen::Vector3d::Zero();  ///< on the robot (x, y, z) [m]
  double deviation = 0.0;       ///< median |error - its link's median error| there [m]
  std::map<Link, double> bias;  ///< each link's median range error there [m]
};

/// |error - its link's median error| of every sample with the tag at `tag` on the robot; each
/// link's median error into `bias` when given.
std::vector<double> rangeDeviations(const std::vector<TagFitSample>& samples,
                                    const Eigen::Vector3d& tag,
                                    std::map<Link, double>* bias = nullptr);

/// The fit from `start`: the lever arm (x, y) when `fit_lever` (the reference must carry the
/// heading), the height when `fit_height`; the rest stays as in `start`. Uses at most 2000
/// samples, evenly spread, for the search, and all of them for the result's deviation and
/// biases. Needs at least 50 samples; fewer give `start` back with its own deviation.
TagFit fitTagOnRobot(const std::vector<TagFitSample>& samples, const Eigen::Vector3d& start,
                     bool fit_lever, bool fit_height);

}  // namespace uwbloc::data
