#include "uwbloc/localization/methods/pf_localizer.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

namespace {
ParticleFilterParams filterParams(const PfLocalizerParams& p) {
  ParticleFilterParams f;
  f.particles = p.particles;
  f.ess_threshold = p.ess;
  f.motion = p.motion;
  f.initial_particles = p.init_n;
  return f;
}
}  // namespace

PfLocalizer::PfLocalizer(const PfLocalizerParams& params, const EstimatorContext& context,
                         bool use_lidar, bool use_uwb)
    : UwbEstimator(params.front, context.anchors),
      params_(params),
      context_(context),
      use_lidar_(use_lidar),
      use_uwb_(use_uwb),
      pf_(filterParams(params), makeResampler(params.resampler), context.seed) {
  if (params_.init != "tracking" && params_.init != "global")
    throw ParamError("parameter 'init' must be tracking or global, got '" + params_.init + "'");
  if (params_.nlos != "lidar" && params_.nlos != "raycast" && params_.nlos != "none")
    throw ParamError("parameter 'nlos' must be lidar, raycast or none, got '" + params_.nlos + "'");
  if (params_.nlos_action != "reject" && params_.nlos_action != "downweight")
    throw ParamError("parameter 'nlos_action' must be reject or downweight");
  if (params_.particles < 1) throw ParamError("parameter 'n' must be at least 1");
  if (params_.init_n < 0) throw ParamError("parameter 'init_n' must be 0 or more");
  if (params_.nlos_suspend < 0) throw ParamError("parameter 'nlos_suspend' must be 0 or more");
  if (params_.swarm != "none" && params_.swarm != "ibas")
    throw ParamError("parameter 'swarm' must be none or ibas, got '" + params_.swarm + "'");
  if (params_.ibas_weights == "fitness")
    weights_ = SwarmWeights::kFitness;
  else if (params_.ibas_weights == "sequential")
    weights_ = SwarmWeights::kSequential;
  else if (params_.ibas_weights == "posterior")
    weights_ = SwarmWeights::kPosterior;
  else
    throw ParamError("parameter 'ibas_weights' must be fitness, sequential or posterior, got '" +
                     params_.ibas_weights + "'");
  nlos_reason_ = "nlos_" + params_.nlos;
  swarm_box_ = optim::Box{Eigen::VectorXd(3), Eigen::VectorXd(3)};
  optim::IbasParams ibas;
  ibas.frame_invariant_mutation = true;  // eq. (25) as printed scales with the map coordinates
  ibas.antenna = params_.ibas_step;
  ibas.random_tie_direction = false;  // a flat epoch fitness carries no information
  ibas.move_mask = Eigen::Vector3d(1.0, 1.0, params_.ibas_theta ? 1.0 : 0.0);
  swarm_ = optim::BeetleSwarm(ibas);
  if ((use_lidar_ || params_.init == "global" || params_.nlos == "raycast") && !context.map)
    throw ParamError("this method needs a map: give the manifest's [dataset] map");
  if (params_.init == "tracking" && !context.initial_pose)
    throw ParamError("tracking initialisation needs a start pose (the dataset's ground truth)");
  if (use_lidar_) field_ = std::make_unique<LikelihoodField>(*context.map, params_.field);
}

void PfLocalizer::reset() { initialise(); }

bool PfLocalizer::nlosSuspended() const {
  return params_.nlos_suspend > 0 && nlos_streak_ >= params_.nlos_suspend;
}

std::vector<std::pair<std::string, std::string>> PfLocalizer::artifacts() const {
  std::vector<std::pair<std::string, std::string>> out;
  if (params_.landmarks && !landmark_map_.landmarks().empty())
    out.emplace_back("landmarks.csv", landmark_map_.toCsv());
  if (!spread_log_.empty()) out.emplace_back("swarm_spread.csv", "t,spread_xy\n" + spread_log_);
  return out;
}

void PfLocalizer::initialise() {
  nlos_streak_ = 0;
  if (params_.init == "tracking") {
    pf_.initUniformBox(*context_.initial_pose,
                       {params_.init_xy, params_.init_xy, params_.init_theta_deg * M_PI / 180.0});
  } else {
    pf_.initUniform(context_.map->freeCells(), context_.map->resolution());
  }
}

double PfLocalizer::epochLogLikelihood(double x, double y, double theta) const {
  double l = 0.0;
  if (epoch_has_scan_ && field_) l += field_->logLikelihood(x, y, theta);
  const double inv2 = 1.0 / (2.0 * params_.front.sigma * params_.front.sigma);
  for (const auto& r : used_ranges_) {
    const double h = uwb::predictRange({x, y, theta}, r.measurement.tag_on_robot, r.anchor);
    l -= (r.measurement.range - h) * (r.measurement.range - h) * inv2;  // eq. (26), in logs
  }
  return l;
}

void PfLocalizer::updateRange(const AcceptedRange& r, const ParticleEstimate& e) {
  const Eigen::Vector3d& tag = r.measurement.tag_on_robot;
  const double d = r.measurement.range;
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
  const bool failed = (params_.nlos == "lidar" && dec.flag_lidar) ||
                      (params_.nlos == "raycast" && dec.flag_raycast);
  epoch_flagged_ += failed;
  const bool flagged = failed && !nlosSuspended();
  double sig = sigma;
  if (flagged) {
    countRejection(nlos_reason_, dec.anchor_id);
    if (params_.nlos_action == "reject") {
      stats_.range_decisions.push_back(dec);
      return;
    }
    sig *= params_.downweight;
  }
  dec.used = true;
  stats_.range_decisions.push_back(dec);
  if (sig == sigma) used_ranges_.push_back(r);  // the swarm's fitness uses the clean ones
  const double inv2 = 1.0 / (2.0 * sig * sig);
  const Eigen::Vector3d anchor = r.anchor;
  pf_.weight([&](double x, double y, double th) {
    const double h = uwb::predictRange({x, y, th}, tag, anchor);
    return -(d - h) * (d - h) * inv2;
  });
}

void PfLocalizer::swarmMove() {
  ParticleSet& ps = pf_.particles();
  const auto n = static_cast<Eigen::Index>(ps.size());
  const Eigen::Index k = 3;  // the heading is always part of the fitness; ibas_theta moves it
  const ParticleEstimate e = pf_.estimate();
  swarm_pos_.resize(n, k);
  for (Eigen::Index i = 0; i < n; ++i) {
    swarm_pos_(i, 0) = ps.x[static_cast<size_t>(i)];
    swarm_pos_(i, 1) = ps.y[static_cast<size_t>(i)];
    // Headings unwrapped around the mean, so the search box does not straddle +-pi.
    if (k == 3)
      swarm_pos_(i, 2) = e.mean.z() + wrapAngle(ps.theta[static_cast<size_t>(i)] - e.mean.z());
  }
  // Search box: the cloud's extent, at least 0.3 m (0.2 rad) around the mean.
  optim::Box& box = swarm_box_;
  for (Eigen::Index c = 0; c < k; ++c) {
    const double half =
        std::max(3.0 * std::sqrt(std::max(e.covariance(c, c), 0.0)), c == 2 ? 0.2 : 0.3);
    box.lo(c) = (c == 2 ? e.mean.z() : e.mean(c)) - half;
    box.hi(c) = (c == 2 ? e.mean.z() : e.mean(c)) + half;
    box.lo(c) = std::min(box.lo(c), swarm_pos_.col(c).minCoeff());
    box.hi(c) = std::max(box.hi(c), swarm_pos_.col(c).maxCoeff());
  }
  const optim::Objective fitness = [&](const Eigen::Ref<const Eigen::VectorXd>& q) {
    return epochLogLikelihood(q(0), q(1), q(2));
  };
  long evals = 0;
  double best = 0.0;
  if (weights_ == SwarmWeights::kPosterior) swarm_start_ = swarm_pos_;
  swarm_.maximize(swarm_pos_, fitness, box, params_.ibas_iterations, params_.ibas_step, pf_.rng(),
                  &best, &evals);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto u = static_cast<size_t>(i);
    ps.x[u] = swarm_pos_(i, 0);
    ps.y[u] = swarm_pos_(i, 1);
    ps.theta[u] = wrapAngle(swarm_pos_(i, 2));
  }
  // Diversity: a collapsed swarm would freeze the estimate.
  double mx = 0, my = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    mx += ps.x[static_cast<size_t>(i)] / n;
    my += ps.y[static_cast<size_t>(i)] / n;
  }
  double var = 0;
  for (Eigen::Index i = 0; i < n; ++i)
    var += (std::pow(ps.x[static_cast<size_t>(i)] - mx, 2) +
            std::pow(ps.y[static_cast<size_t>(i)] - my, 2)) /
           n;
  const double spread = std::sqrt(var);
  char row[64];
  std::snprintf(row, sizeof row, "%.6f,%.5f\n", epoch_t_, spread);
  spread_log_ += row;
  // Eq. (28): the weights are the fitness at the moved positions, normalised. The swarm has
  // already evaluated it there; only particles moved again by a diversity injection need it anew.
  const Eigen::VectorXd& fitness_at = swarm_.values();
  if (spread < params_.min_spread) {
    std::normal_distribution<double> g(0.0, params_.min_spread);
    for (size_t i = 0; i < ps.size(); ++i) {
      ps.x[i] += g(pf_.rng());
      ps.y[i] += g(pf_.rng());
      ps.log_w[i] = epochLogLikelihood(ps.x[i], ps.y[i], ps.theta[i]);
    }
    ++stats_.events["swarm_diversity_injection"];
  } else {
    for (size_t i = 0; i < ps.size(); ++i) ps.log_w[i] = fitness_at(static_cast<Eigen::Index>(i));
  }
  if (weights_ != SwarmWeights::kFitness) {
    // Sequential importance weights: the weight each particle carried into this epoch (its
    // history since the last resampling) times the epoch's likelihood.
    for (size_t i = 0; i < ps.size(); ++i) ps.log_w[i] += prior_log_w_[i];
  }
  if (weights_ == SwarmWeights::kPosterior) {
    // And the predicted density's ratio between where the swarm left each particle and where
    // the motion model put it (the heading only when the swarm moves it: otherwise its rows
    // of the information matrix stay zero).
    Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
    if (params_.ibas_theta)
      info = (predicted_.covariance + 1e-6 * Eigen::Matrix3d::Identity()).inverse();
    else
      info.topLeftCorner<2, 2>() =
          (predicted_.covariance.topLeftCorner<2, 2>() + 1e-6 * Eigen::Matrix2d::Identity())
              .inverse();
    const auto offset = [&](double x, double y, double th) {
      const Eigen::Vector3d d(x - predicted_.mean.x(), y - predicted_.mean.y(),
                              wrapAngle(th - predicted_.mean.z()));
      return 0.5 * d.dot(info * d);
    };
    for (size_t i = 0; i < ps.size(); ++i) {
      const auto r = static_cast<Eigen::Index>(i);
      ps.log_w[i] += offset(swarm_start_(r, 0), swarm_start_(r, 1), swarm_start_(r, 2)) -
                     offset(ps.x[i], ps.y[i], ps.theta[i]);
    }
  }
  pf_.normalize();
}

std::optional<PoseEstimate> PfLocalizer::finishEpoch() {
  epoch_open_ = false;
  used_ranges_.clear();
  if (params_.swarm == "ibas" && weights_ != SwarmWeights::kFitness) {
    prior_log_w_ = pf_.particles().log_w;
    if (weights_ == SwarmWeights::kPosterior) predicted_ = pf_.estimate();
  }
  if (epoch_has_scan_) {
    if (field_->rays() == 0) {
      countRejection("scan_without_returns");
    } else {
      const LikelihoodField& f = *field_;
      pf_.weight([&f](double x, double y, double th) { return f.logLikelihood(x, y, th); });
    }
  }
  if (!epoch_ranges_.empty()) {
    // The NLOS test uses the estimate after the motion and the LiDAR update.
    pf_.normalize();
    const ParticleEstimate e = pf_.estimate();
    epoch_flagged_ = 0;
    if (nlosSuspended()) ++stats_.events["nlos_test_suspended"];
    for (const auto& r : epoch_ranges_) updateRange(r, e);
    const auto ranges = static_cast<int>(epoch_ranges_.size());
    nlos_streak_ = epoch_flagged_ >= 2 && 2 * epoch_flagged_ > ranges ? nlos_streak_ + 1 : 0;
  }
  if (params_.swarm == "ibas") {
    pf_.normalize();
    swarmMove();
    if (params_.ibas_resample) pf_.normalizeAndResample();
  } else {
    pf_.normalizeAndResample();
  }
  const ParticleEstimate e = pf_.estimate();
  PoseEstimate est;
  est.t = epoch_t_;
  est.pose = e.mean;
  est.covariance = e.covariance;
  if (params_.landmarks && epoch_has_scan_) {
    // Corners seen from the current estimate grow the landmark map.
    const Eigen::Matrix2d r =
        Eigen::Matrix2d::Identity() * params_.landmark_sigma * params_.landmark_sigma;
    for (const auto& c : extractCorners(extractLines(epoch_scan_, extraction_), extraction_))
      landmark_map_.integrate(est.pose, est.covariance, c, r);
  }
  epoch_has_scan_ = false;
  epoch_ranges_.clear();
  return est;
}

std::optional<PoseEstimate> PfLocalizer::doFinish() {
  if (epoch_open_) return finishEpoch();
  return std::nullopt;
}

std::optional<PoseEstimate> PfLocalizer::doProcess(const Event& event) {
  if (!pf_.initialised()) initialise();
  const double t = eventTime(event);
  std::optional<PoseEstimate> out;
  // Any later event closes the open epoch.
  if (epoch_open_ && t > epoch_t_) out = finishEpoch();
  if (const auto* odo = std::get_if<OdometryIncrement>(&event)) {
    if (!odo->delta.allFinite()) {
      countRejection("non_finite_odometry");
      return out;
    }
    if (epoch_open_) out = finishEpoch();  // motion at the epoch's own time: close it first
    pf_.predict(odo->delta);
    return out;
  }
  if (const auto* scan = std::get_if<LaserScan>(&event)) {
    if (!use_lidar_) return out;
    field_->setScan(*scan);
    if (params_.landmarks) epoch_scan_ = *scan;  // kept only for corner extraction
    epoch_has_scan_ = true;
  } else {
    if (!use_uwb_) return out;
    const auto accepted = acceptRange(event);
    if (!accepted) return out;
    epoch_ranges_.push_back(*accepted);
  }
  if (!epoch_open_) {
    epoch_open_ = true;
    epoch_t_ = t;
  }
  return out;
}

}  // namespace uwbloc::loc
