// lidar-icp: LiDAR odometry by ICP (the classic loop of MRPT's CICP, refined point-to-line) of each
// scan against a local map, seeded with the odometry accumulated since the last keyframe. A new
// keyframe starts when the robot has moved `kf_dist` or turned `kf_angle` from the last one:
// aligning every scan to its predecessor would add each alignment's small error (a few mrad) at
// the scan rate. The local map is the union of the keyframes taken within `map_radius` of the
// newest and within `map_path` of travel: a scan aligned to what several keyframes saw drifts
// less than one aligned to the last keyframe alone, above all while turning on the spot. It still
// accumulates error like any odometry: this is the PF-IBAS paper's LiDAR-only baseline. It starts
// at the start pose's time: the odometry and scans before it are skipped and counted.
#pragma once

#include <memory>

#include "uwbloc/localization/estimator.hpp"

namespace uwbloc::loc {

struct LidarIcpParams {
  int max_iterations = 40;          ///< ICP iterations per alignment
  double threshold_dist = 0.75;     ///< initial correspondence distance [m]
  double threshold_ang_deg = 0.15;  ///< angular part of the correspondence threshold [deg]
  double alfa = 0.5;                ///< threshold shrink factor per convergence
  double smallest_dist = 0.05;      ///< final correspondence distance [m]
  double min_range = 0.1;           ///< scan points closer than this are dropped [m]
  double max_range = 30.0;          ///< scan points beyond this are dropped [m]
  int decimation = 1;               ///< use every n-th ray
  double min_goodness = 0.4;        ///< below this ICP is not trusted: odometry is used instead
  double kf_dist = 0.5;             ///< new keyframe after this translation [m]
  double kf_angle_deg = 15.0;       ///< new keyframe after this rotation [deg]
  double search_deg =
      40.0;  ///< on a poor fit or a turn, headings tried about the seed, every 20 [deg]
  double search_turn_deg = 10.0;  ///< the odometry's turn since the keyframe that searches [deg]
  double line_dist = 0.5;    ///< point-to-line refinement: matching distance [m]; 0: off
  double map_radius = 15.0;  ///< the local map keeps keyframes this near the newest [m]
  double map_path = 30.0;    ///< ... taken within this distance travelled [m]

  template <class V>
  void visit(V&& v) {
    v("iters", max_iterations, "ICP iterations per alignment");
    v("dist", threshold_dist, "initial correspondence distance [m]");
    v("ang", threshold_ang_deg, "angular part of the correspondence threshold [deg]");
    v("alfa", alfa, "threshold shrink factor");
    v("min_dist", smallest_dist, "final correspondence distance [m]");
    v("min_range", min_range, "drop closer points [m]");
    v("max_range", max_range, "drop farther points [m]");
    v("decimation", decimation, "use every n-th ray");
    v("min_goodness", min_goodness, "fall back to odometry below this ICP goodness");
    v("kf_dist", kf_dist, "new keyframe after this translation [m] (0: every scan)");
    v("kf_angle", kf_angle_deg, "new keyframe after this rotation [deg]");
    v("search", search_deg,
      "when the fit from the odometry's seed is poor, or the odometry turned more than "
      "search_turn since the keyframe, the seed's heading is also tried this far either side, "
      "every 20 deg, and the best fit kept [deg] (0: off)");
    v("search_turn", search_turn_deg,
      "the odometry's turn since the keyframe beyond which the headings about its seed are "
      "searched even on a good fit: a fast turn's odometry can be 20-35 deg off the scans [deg]");
    v("line_dist", line_dist,
      "point-to-line refinement (PL-ICP's metric) of each alignment: the farthest a scan point "
      "may lie from its nearest keyframe point, and two keyframe points from each other, to "
      "make a line [m] (0: point-to-point only)");
    v("map_radius", map_radius,
      "each scan is aligned to a local map: the keyframes taken within this distance of the "
      "newest one [m] (0: the last keyframe alone)");
    v("map_path", map_path,
      "... and within this distance travelled, so that a place revisited after the drift of a "
      "loop is not matched against its older copy [m] (0: the last keyframe alone)");
  }
};

class LidarIcp : public Estimator {
 public:
  LidarIcp(const LidarIcpParams& params, const EstimatorContext& context);
  ~LidarIcp() override;

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;

 private:
  struct Impl;
  LidarIcpParams params_;
  Eigen::Vector3d pose_;
  Eigen::Vector3d keyframe_pose_;
  Eigen::Vector3d odometry_since_keyframe_ = Eigen::Vector3d::Zero();
  double start_t_;  ///< the start pose's time: odometry and scans before it are skipped
  std::unique_ptr<Impl> impl_;
};

}  // namespace uwbloc::loc
