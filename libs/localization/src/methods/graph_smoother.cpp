#include "uwbloc/localization/methods/graph_smoother.hpp"

#include <cmath>

namespace uwbloc::loc {

GraphSmoother::GraphSmoother(const GraphSmootherParams& params, const EstimatorContext& context)
    : UwbEstimator(params.front, context.anchors),
      params_(params),
      dead_reckoning_(context.initial_pose.value_or(Eigen::Vector3d::Zero())) {
  if (!context.initial_pose)
    throw ParamError("graph-uwb-odom needs a start pose (the dataset's ground truth)");
  graph_.setAnchors(context.anchors);
}

std::optional<PoseEstimate> GraphSmoother::doProcess(const Event& event) {
  const double t = eventTime(event);
  if (!started_) {
    graph_.addPose(dead_reckoning_);
    times_.push_back(t);
    started_ = true;
  }
  if (const auto* odo = std::get_if<OdometryIncrement>(&event)) {
    if (!odo->delta.allFinite()) {
      countRejection("non_finite_odometry");
      return std::nullopt;
    }
    dead_reckoning_ = composePose(dead_reckoning_, odo->delta);
    const int to = graph_.addPose(dead_reckoning_);
    times_.push_back(odo->t);
    // Odometry noise grows with the motion.
    const double dist = odo->delta.head<2>().norm();
    const double sxy = params_.odom_sigma_xy + params_.odom_sigma_xy_per_m * dist;
    const double sth =
        params_.odom_sigma_theta + params_.odom_sigma_theta_per_rad * std::abs(odo->delta.z());
    graph_.addOdometry(to - 1, to, odo->delta, Eigen::Vector3d(sxy, sxy, sth));
    return std::nullopt;
  }
  const auto accepted = acceptRange(event);
  if (!accepted) return std::nullopt;
  graph_.addRange(static_cast<int>(graph_.poses()) - 1, accepted->measurement.anchor_id,
                  accepted->measurement.range, accepted->measurement.tag_on_robot);
  return std::nullopt;
}

std::vector<PoseEstimate> GraphSmoother::doFinishAll() {
  graph::RangeGraphParams p;
  p.range_sigma = params_.front.sigma;
  p.loss = params_.loss;
  p.loss_scale = params_.loss_scale;
  p.estimate_bias = params_.estimate_bias;
  p.estimate_anchors = params_.estimate_anchors;
  p.anchor_prior_sigma = params_.anchor_prior;
  p.max_iterations = params_.iterations;
  graph_.build(p);
  const auto solution = graph_.solve();
  if (!solution.usable) countRejection("graph_not_usable");
  std::vector<PoseEstimate> out;
  out.reserve(graph_.poses());
  for (size_t i = 0; i < graph_.poses(); ++i) {
    PoseEstimate e;
    e.t = times_[i];
    e.pose = graph_.pose(i);
    out.push_back(e);
  }
  return out;
}

}  // namespace uwbloc::loc
