// graph-uwb-odom: batch smoothing of a whole run over a Ceres range + odometry graph. One pose
// vertex per odometry increment (initialised by dead reckoning from the start pose), each range
// attached to the latest pose, anchors fixed or self-calibrated, optional per-anchor range bias,
// robust loss for NLOS. The trajectory is produced at the end of the stream.
#pragma once

#include "uwbloc/localization/graph/range_graph.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct GraphSmootherParams {
  RangeFrontEndParams front;               ///< range checks; sigma is the range edges' std
  std::string loss = "cauchy";             ///< none, huber or cauchy
  double loss_scale = 2.0;                 ///< in standard deviations
  double odom_sigma_xy = 0.01;             ///< per increment [m] ...
  double odom_sigma_xy_per_m = 0.05;       ///< ... plus this per metre moved
  double odom_sigma_theta = 0.005;         ///< per increment [rad] ...
  double odom_sigma_theta_per_rad = 0.05;  ///< ... plus this per radian turned
  bool estimate_bias = false;              ///< a range bias per anchor
  bool estimate_anchors = false;           ///< anchors' x, y with a prior
  double anchor_prior = 0.5;               ///< [m]
  int iterations = 100;

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("loss", loss, "robust loss on ranges: none, huber or cauchy");
    v("loss_scale", loss_scale, "robust-loss scale [std]");
    v("odom_xy", odom_sigma_xy, "odometry edge std per increment [m]");
    v("odom_xy_per_m", odom_sigma_xy_per_m, "odometry edge std per metre moved");
    v("odom_th", odom_sigma_theta, "odometry edge heading std per increment [rad]");
    v("odom_th_per_rad", odom_sigma_theta_per_rad, "odometry edge heading std per radian turned");
    v("bias", estimate_bias, "estimate a range bias per anchor");
    v("anchors", estimate_anchors, "self-calibrate the anchors (x, y)");
    v("anchor_prior", anchor_prior, "anchor prior std [m]");
    v("iterations", iterations, "solver iterations");
  }
};

class GraphSmoother : public UwbEstimator {
 public:
  GraphSmoother(const GraphSmootherParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::vector<PoseEstimate> doFinishAll() override;

 private:
  GraphSmootherParams params_;
  graph::RangeGraph graph_;
  std::vector<double> times_;
  Eigen::Vector3d dead_reckoning_;
  bool started_ = false;
};

}  // namespace uwbloc::loc
