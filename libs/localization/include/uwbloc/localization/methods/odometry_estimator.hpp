// odom: dead reckoning from odometry increments, started at the first ground-truth pose and at
// its time: increments stamped at or before it (the motion that brought the robot to that pose)
// are skipped and counted as odometry_before_start.
#pragma once

#include "uwbloc/localization/estimator.hpp"

namespace uwbloc::loc {

struct OdometryParams {
  double heading_offset = 0.0;  ///< added to the start heading (datasets whose odometry heading
                                ///< convention differs from the reference's) [rad]
  template <class V>
  void visit(V&& v) {
    v("heading_offset", heading_offset, "added to the start heading [rad]");
  }
};

class OdometryEstimator : public Estimator {
 public:
  OdometryEstimator(const OdometryParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;

 private:
  Eigen::Vector3d pose_;
  double start_t_;
};

}  // namespace uwbloc::loc
