#include "uwbloc/localization/methods/pf_localizer.hpp"

#include <cmath>

#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

PfLocalizer::PfLocalizer(const PfLocalizerParams& params, const EstimatorContext& context,
                         bool use_lidar, bool use_uwb)
    : UwbEstimator(params.front, context.anchors),
      params_(params),
      context_(context),
      use_lidar_(use_lidar),
      use_uwb_(use_uwb),
      pf_({params.particles, params.ess, params.motion}, makeResampler(params.resampler),
          context.seed) {
  if (params_.init != "tracking" && params_.init != "global")
    throw ParamError("parameter 'init' must be tracking or global, got '" + params_.init + "'");
  if (params_.nlos != "lidar" && params_.nlos != "raycast" && params_.nlos != "none")
    throw ParamError("parameter 'nlos' must be lidar, raycast or none, got '" + params_.nlos + "'");
  if (params_.nlos_action != "reject" && params_.nlos_action != "downweight")
    throw ParamError("parameter 'nlos_action' must be reject or downweight");
  if (params_.particles < 1) throw ParamError("parameter 'n' must be at least 1");
  if ((use_lidar_ || params_.init == "global" || params_.nlos == "raycast") && !context.map)
    throw ParamError("this method needs a map: give the manifest's [dataset] map");
  if (params_.init == "tracking" && !context.initial_pose)
    throw ParamError("tracking initialisation needs a start pose (the dataset's ground truth)");
  if (use_lidar_) field_ = std::make_unique<LikelihoodField>(*context.map, params_.field);
}

void PfLocalizer::reset() { initialise(); }

std::vector<std::pair<std::string, std::string>> PfLocalizer::artifacts() const {
  if (!params_.landmarks || landmark_map_.landmarks().empty()) return {};
  return {{"landmarks.csv", landmark_map_.toCsv()}};
}

void PfLocalizer::initialise() {
  if (params_.init == "tracking") {
    pf_.initUniformBox(*context_.initial_pose,
                       {params_.init_xy, params_.init_xy, params_.init_theta_deg * M_PI / 180.0});
  } else {
    pf_.initUniform(context_.map->freeCells(), context_.map->resolution());
  }
}

std::optional<PoseEstimate> PfLocalizer::output(double t) {
  pf_.normalizeAndResample();
  const ParticleEstimate e = pf_.estimate();
  PoseEstimate est;
  est.t = t;
  est.pose = e.mean;
  est.covariance = e.covariance;
  return est;
}

void PfLocalizer::updateRange(const AcceptedRange& r) {
  const Eigen::Vector3d& tag = r.measurement.tag_on_robot;
  const double d = r.measurement.range;
  // Predict the range from the current estimate (after motion and LiDAR).
  pf_.normalizeAndResample();
  const ParticleEstimate e = pf_.estimate();
  Eigen::RowVector3d j;
  const double d_hat = uwb::predictRange(e.mean, tag, r.anchor, &j);
  const double sigma = params_.front.sigma;
  const double s = sigma * sigma + (j * e.covariance * j.transpose())(0, 0);
  RangeDecision dec;
  dec.t = r.measurement.t;
  dec.anchor_id = r.measurement.anchor_id;
  dec.range = d;
  dec.flag_lidar = std::abs(d - d_hat) > params_.nlos_k * std::sqrt(s);
  if (context_.map) {
    const Eigen::Vector3d tag_world = uwb::tagPosition(e.mean, tag);
    dec.flag_raycast = context_.map->segmentBlocked(tag_world.head<2>(), r.anchor.head<2>(),
                                                    1.5 * context_.map->resolution());
  }
  const bool flagged = (params_.nlos == "lidar" && dec.flag_lidar) ||
                       (params_.nlos == "raycast" && dec.flag_raycast);
  double sig = sigma;
  if (flagged) {
    countRejection("nlos_" + params_.nlos, dec.anchor_id);
    if (params_.nlos_action == "reject") {
      stats_.range_decisions.push_back(dec);
      return;
    }
    sig *= params_.downweight;
  }
  dec.used = true;
  stats_.range_decisions.push_back(dec);
  const double inv2 = 1.0 / (2.0 * sig * sig);
  const Eigen::Vector3d anchor = r.anchor;
  pf_.weight([&](double x, double y, double th) {
    const double h = uwb::predictRange({x, y, th}, tag, anchor);
    return -(d - h) * (d - h) * inv2;
  });
}

std::optional<PoseEstimate> PfLocalizer::doProcess(const Event& event) {
  if (!pf_.initialised()) initialise();
  if (const auto* odo = std::get_if<OdometryIncrement>(&event)) {
    if (!odo->delta.allFinite()) {
      countRejection("non_finite_odometry");
      return std::nullopt;
    }
    pf_.predict(odo->delta);
    return std::nullopt;
  }
  if (const auto* scan = std::get_if<LaserScan>(&event)) {
    if (!use_lidar_) return std::nullopt;
    field_->setScan(*scan);
    if (field_->rays() == 0) {
      countRejection("scan_without_returns");
      return output(scan->t);
    }
    const LikelihoodField& f = *field_;
    pf_.weight([&f](double x, double y, double th) { return f.logLikelihood(x, y, th); });
    auto est = output(scan->t);
    if (params_.landmarks && est) {
      // Corners seen from the current estimate grow the landmark map.
      const Eigen::Matrix2d r =
          Eigen::Matrix2d::Identity() * params_.landmark_sigma * params_.landmark_sigma;
      for (const auto& c : extractCorners(extractLines(*scan, extraction_), extraction_))
        landmark_map_.integrate(est->pose, est->covariance, c, r);
    }
    return est;
  }
  if (!use_uwb_) return std::nullopt;
  const auto accepted = acceptRange(event);
  if (!accepted) return std::nullopt;
  updateRange(*accepted);
  return output(accepted->measurement.t);
}

}  // namespace uwbloc::loc
