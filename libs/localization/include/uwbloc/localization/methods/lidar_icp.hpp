// lidar-icp: LiDAR odometry by scan-to-scan ICP (MRPT's CICP), each alignment seeded with the
// odometry accumulated since the previous scan. It accumulates error like any odometry: this is
// the PF-IBAS paper's LiDAR-only baseline.
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
  Eigen::Vector3d odometry_since_scan_ = Eigen::Vector3d::Zero();
  std::unique_ptr<Impl> impl_;
};

}  // namespace uwbloc::loc
