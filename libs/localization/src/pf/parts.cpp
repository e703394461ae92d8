#include "uwbloc/localization/pf/parts.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

// ---------------------------------------------------------------- LiDAR likelihood field

LidarFieldMeasurement::LidarFieldMeasurement(const LidarPartParams& params,
                                             const std::shared_ptr<const OccupancyMap>& map)
    : params_(params), field_(map, params.field) {}

bool LidarFieldMeasurement::take(const Event& event, EstimatorStatistics&) {
  const auto* scan = std::get_if<LaserScan>(&event);
  if (!scan) return false;
  field_.setScan(*scan);
  if (params_.landmarks) scan_ = *scan;  // kept only for corner extraction
  has_scan_ = true;
  return true;
}

void LidarFieldMeasurement::weight(ParticleFilter& pf, EstimatorStatistics& stats) {
  if (!has_scan_) return;
  if (field_.rays() == 0) {
    countRejection(stats, "scan_without_returns");
    return;
  }
  const LikelihoodField& f = field_;
  double best = -std::numeric_limits<double>::infinity();
  scan_log_l_.clear();
  pf.weight([&](double x, double y, double th) {
    const double l = f.logLikelihood(x, y, th);
    scan_log_l_.push_back(l);
    if (l > best) {
      best = l;
      best_pose_ = {x, y, th};
    }
    return l;
  });
  if (params_.respread > 0.0) respreadOnPoorFit(pf, stats);
}

void LidarFieldMeasurement::respreadOnPoorFit(ParticleFilter& pf, EstimatorStatistics& stats) {
  const double fit = field_.fitFraction(best_pose_.x(), best_pose_.y(), best_pose_.z(),
                                        0.5 * params_.field.max_dist);
  if (!respread_level_.poor(fit, params_.lost_fit)) return;
  // Every k-th particle (the resampler leaves copies side by side, so each hypothesis keeps
  // some) is re-drawn uniformly in the box around the estimate, and weighed by this scan in
  // place of what it scored where it was. (Widening the box with each poor scan in a row, to
  // reach a heading off by more than its width, let wrong headings win: CARMEN aces+uwb pf-ibas
  // 0.139 / 0.164 -> 0.218 / 0.368 m, mean / worst of 5 seeds.)
  ParticleSet& ps = pf.particles();
  const ParticleEstimate e = pf.estimate();
  // A cloud already wider than the box (spread over the map by a global start or a
  // relocalisation) has nothing to gain from it, and would lose half its particles to it.
  const double half_xy = params_.respread_xy;
  if (std::max(e.covariance(0, 0), e.covariance(1, 1)) > half_xy * half_xy) return;
  const auto step = static_cast<size_t>(std::max(1.0, std::round(1.0 / params_.respread)));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const double half_theta = params_.respread_theta * M_PI / 180.0;
  double best = field_.logLikelihood(best_pose_.x(), best_pose_.y(), best_pose_.z());
  for (size_t i = step - 1; i < ps.size() && i < scan_log_l_.size(); i += step) {
    ps.x[i] = e.mean.x() + half_xy * u(pf.rng());
    ps.y[i] = e.mean.y() + half_xy * u(pf.rng());
    ps.theta[i] = wrapAngle(e.mean.z() + half_theta * u(pf.rng()));
    const double l = field_.logLikelihood(ps.x[i], ps.y[i], ps.theta[i]);
    ps.log_w[i] += boundedLogLikelihood(l) - boundedLogLikelihood(scan_log_l_[i]);
    if (l > best) {
      best = l;
      best_pose_ = {ps.x[i], ps.y[i], ps.theta[i]};
    }
  }
  ++stats.events["scan_fit_respread"];
}

double LidarFieldMeasurement::addLogLikelihood(double l, double x, double y, double th) const {
  return has_scan_ ? l + field_.logLikelihood(x, y, th) : l;
}

void LidarFieldMeasurement::endEpoch(const PoseEstimate& est) {
  if (has_scan_ && hold_off_ > 0) {
    --hold_off_;
  } else if (has_scan_ && field_.rays() > 0 && params_.lost_scans > 0) {
    // The scan's fit at the estimate, against its usual level (a running mean over the scans
    // judged not lost; the first 10 only build it).
    // At the particle the scan fits best: in clutter the mean may fit poorly while some
    // particle still fits; after a kidnapping none does.
    const double fit = field_.fitFraction(best_pose_.x(), best_pose_.y(), best_pose_.z(),
                                          0.5 * params_.field.max_dist);
    low_fit_streak_ = lost_level_.poor(fit, params_.lost_fit) ? low_fit_streak_ + 1 : 0;
  }
  if (params_.landmarks && has_scan_) {
    // Corners seen from the current estimate grow the landmark map.
    const Eigen::Matrix2d r =
        Eigen::Matrix2d::Identity() * params_.landmark_sigma * params_.landmark_sigma;
    for (const auto& c : extractCorners(extractLines(scan_, extraction_), extraction_))
      landmark_map_.integrate(est.pose, est.covariance, c, r);
  }
  has_scan_ = false;
}

void LidarFieldMeasurement::addArtifacts(
    std::vector<std::pair<std::string, std::string>>& out) const {
  if (params_.landmarks && !landmark_map_.landmarks().empty())
    out.emplace_back("landmarks.csv", landmark_map_.toCsv());
}

// ---------------------------------------------------------------- UWB ranges

UwbRangeMeasurement::UwbRangeMeasurement(const UwbPartParams& params,
                                         const EstimatorContext& context, bool with_lidar)
    : params_(params),
      front_(params.front, context.anchors, resolveNlosModel(params.front, context), TagUse::kAll,
             primaryTag(context)),
      map_(context.map),
      nlos_reason_(std::string("nlos_") + enumName(params.nlos)),
      pose_gate_(params.nlos_k * params.nlos_k),
      noise_(params.front.sigmaValue()),
      nlos_state_(params.nlos_memory),
      learn_at_lidar_(with_lidar && params.calib_lidar > 0.0 && params.mixture &&
                      params.front.sigma.isAuto() && params.bias != BiasMode::kOn) {
  if (params_.nlos == NlosTest::kRaycast && !map_)
    throw ParamError("nlos=raycast needs a map: give the manifest's [dataset] map");
}

namespace {
// A range event through the front end's checks: the accepted range (counted), or nothing (a
// rejection counted with its reason, or not a range).
std::optional<AcceptedRange> acceptRange(RangeFrontEnd& front, const Event& event,
                                         EstimatorStatistics& stats) {
  const auto* range = std::get_if<uwb::Range>(&event);
  if (!range) return std::nullopt;
  uwb::RejectReason reason{};
  auto accepted = front.accept(*range, &reason);
  if (!accepted) {
    rejectRange(stats, *range, uwb::toString(reason));
    return std::nullopt;
  }
  ++stats.accepted_ranges;
  return accepted;
}
}  // namespace

bool UwbRangeMeasurement::take(const Event& event, EstimatorStatistics& stats) {
  auto accepted = acceptRange(front_, event, stats);
  if (!accepted) return false;
  if (accepted->nlos_decision) ++stats.events[accepted->nlos_decision];
  epoch_.push_back(*accepted);
  return true;
}

std::optional<Calibration> UwbRangeMeasurement::calibration() const {
  if (params_.calib <= 0.0 || (!params_.front.sigma.isAuto() && params_.bias == BiasMode::kOff))
    return std::nullopt;
  std::ostringstream spec;
  // The bias trial frees one bias common to every anchor first: a delay common to every anchor
  // hides in the noise from the offsets (simulated greenhouse R3, 1 m under 1 m noise: uwb-pf
  // 1.178 m without the trial, 0.188 m with it; R2 0.360 -> 0.115 m). When it does not stand, a
  // bias per anchor is tried, and stands only when the ranges alone take biases too
  // (bias_trial_confirm): over a 60 s batch the odometry's path errors pass for biases per
  // anchor (MRPT demo without its manifest's sigma, biases taken: uwb-pf 0.139 -> 0.269 m,
  // pf-ibas 0.115 -> 0.147 m), while a 0.5 m bias on one of three simulated anchors, which the
  // common bias cannot take, cost uwb-pf 12.6x the true model's error without the confirmed
  // trial (uwbloc sensitivity, seeds 1-2).
  spec << "graph-uwb-odom:sigma=" << params_.front.sigma << ",bias=" << enumName(params_.bias)
       << ",bias_trial=1,bias_trial_common=1,bias_trial_confirm=1";
  // The odometry model stays as given (odom_noise=1): learnt over the batch, it moved uwb-pf both
  // ways by up to 0.007 m on the simulated rooms (agv_room 0.024 -> 0.019, tracking_los 0.042 ->
  // 0.048 m) and nothing else (`uwbloc benchmark --seeds 1`, the fused filters unchanged).
  spec << ",odom_noise=1";
  // The path's residuals under the robust loss (the particle filters learn their own mixture
  // from them). From the path solved under the mixture, uwb-pf moved both ways: CARMEN
  // intel+uwb 0.268 -> 0.226, office 0.051 -> 0.042, but pfibas_room 0.025 -> 0.033, plate
  // 0.028 -> 0.031, aces+uwb 0.159 -> 0.162 m; the fused filters, which learn at the LiDAR's
  // pose, not at all (`uwbloc benchmark --seeds 1 -m
  // uwb-pf,fused-pf,pf-sir,pf-ibas,pf-ibas+graph`).
  spec << ",nlos_mixture=0";
  Calibration c{spec.str(), params_.calib, {}, 0.0};
  if (learn_at_lidar_) {
    // Its particles stay at the last odometry increment between increments (carry=0): carried to
    // each range's time, the residuals of the first 120 s on CARMEN intel with six simulated
    // anchors (tests/test_scenarios.cpp) chose a bias per anchor over the mixture by BIC (4927
    // against 5079; 5018 against 4668 uncarried), and fused-pf went from 0.106 to 0.442 m. The
    // choice between the two models is that close there; the filter itself carries.
    c.mixture_learner = "lidar-mcl:range_model=1,landmarks=0,carry=0";
    c.mixture_span = std::max(params_.calib_lidar, params_.calib);
  }
  return c;
}

void UwbRangeMeasurement::learnTagScales(const EstimatorStatistics& learnt,
                                         EstimatorStatistics& stats) {
  // One std learnt over several tags is the many ranges' std: the tags that range most set it,
  // and a tag that ranges less and worse would fail the NLOS test at it (the MRPT demo with two
  // simulated tags: 3 630 simulated ranges per tag and anchor at 0.05 m against the real tag's
  // 336 at 0.08-0.23 m; uwb-pf learnt 0.079 m and rejected 2 098 good ranges).
  const auto& tags = learnt.estimated_tag_noise;
  if (tags.size() < 2) return;
  stats.estimated_tag_noise = tags;
  if (!params_.tag_sigma) return;
  double sum = 0.0;
  long n = 0;
  for (const auto& [tag, t] : tags) {
    sum += static_cast<double>(t.ranges) * t.sigma * t.sigma;
    n += t.ranges;
  }
  if (n == 0 || sum <= 0.0) return;
  const double pooled = std::sqrt(sum / static_cast<double>(n));
  constexpr double kTagWider = 1.25;
  constexpr long kMinRanges = 30;
  for (const auto& [tag, t] : tags)
    if (t.ranges >= kMinRanges && t.sigma > kTagWider * pooled) {
      tag_scale_[tag] = t.sigma / pooled;
      ++stats.events["tag_sigma_widened"];
    }
}

void UwbRangeMeasurement::calibrate(const EstimatorStatistics& learnt, EstimatorStatistics& stats) {
  // The mixture's NLOS part explains the long ranges that biases would take up on the anchors
  // mostly out of sight, and no bias is applied under it (bias=1 still applies the learnt ones).
  // Its own offsets per anchor are not taken either: from a path that the NLOS ranges bent, they
  // read 0.1-0.36 m short (CARMEN intel with simulated UWB: uwb-pf 0.506 m with them, 0.223 m
  // without).
  const bool mixture =
      params_.mixture && params_.front.sigma.isAuto() && learnt.estimated_range_mixture.has_value();
  const bool biased =
      params_.bias == BiasMode::kOn || (!mixture && learnt.events.count("range_bias_estimated"));
  // Biases that the odometry's path took but the ranges alone did not (bias_trial_confirm).
  if (learnt.events.count("range_bias_unconfirmed")) ++stats.events["range_bias_unconfirmed"];
  noise_.learn(learnt.estimated_noise, biased,
               params_.front.sigma.isAuto() ? learnt.estimated_range_sigma : std::nullopt,
               learnt.estimated_range_scale);
  noise_.report(stats);
  learnTagScales(learnt, stats);
  if (mixture) {
    mixture_ = learnt.estimated_range_mixture;
    // The mixture gives the shape (how many ranges read long, and by how much). Learnt at the
    // LiDAR's pose, it is taken as fitted: the scans hold the cloud together. Otherwise its LOS
    // std is only ever widened to the learnt Gaussian's, as a learnt std is elsewhere: with 300
    // particles and ranges at 60 Hz, a likelihood as sharp as the LOS noise collapses the cloud
    // and it loses the robot (CARMEN aces with simulated UWB: uwb-pf 19.8 m at the LOS std of
    // 0.086 m, 0.172 m at the Gaussian's 0.306 m).
    if (!learn_at_lidar_) mixture_->sigma = std::max(mixture_->sigma, noise_.sigma());
    if (params_.range_share.value) mixture_->weight = *params_.range_share.value;
    stats.estimated_range_mixture = mixture_;
    ++stats.events["range_mixture_in_force"];
    if (learn_at_lidar_) ++stats.events["range_mixture_at_lidar_pose"];
  }
}

// Under the mixture learnt at the LiDAR's pose a range fails the test only when neither part
// explains it: a handful in 140 000 on CARMEN intel with simulated UWB while the filter tracks,
// and half of them once it has locked onto the wrong corridor, whose scans fit the map as well.
bool UwbRangeMeasurement::lost() const {
  if (params_.lost_ranges <= 0 || recent_failed_.size() < static_cast<size_t>(params_.lost_ranges))
    return false;
  const auto failed = std::count(recent_failed_.begin(), recent_failed_.end(), true);
  return 2 * failed > static_cast<long>(recent_failed_.size());
}

bool UwbRangeMeasurement::suspended() const {
  return params_.nlos_suspend > 0 && nlos_streak_ >= params_.nlos_suspend;
}

void UwbRangeMeasurement::weight(ParticleFilter& pf, EstimatorStatistics& stats) {
  used_.clear();
  if (epoch_.empty()) return;
  // The NLOS test uses the estimate after the motion and the epoch's other updates (LiDAR).
  pf.normalize();
  const ParticleEstimate e = pf.estimate();
  epoch_flagged_ = 0;
  if (suspended()) ++stats.events["nlos_test_suspended"];
  for (const auto& r : epoch_) weightRange(pf, r, e, stats);
  const auto ranges = static_cast<int>(epoch_.size());
  nlos_streak_ = epoch_flagged_ >= 2 && 2 * epoch_flagged_ > ranges ? nlos_streak_ + 1 : 0;
}

void UwbRangeMeasurement::weightRange(ParticleFilter& pf, const AcceptedRange& r,
                                      const ParticleEstimate& e, EstimatorStatistics& stats) {
  const Eigen::Vector3d& tag = r.measurement.tag_on_robot;
  Eigen::RowVector3d j;
  const double d_hat = uwb::predictRange(e.mean, tag, r.anchor, &j);
  const double state_variance = (j * e.covariance * j.transpose())(0, 0);
  // The test and the likelihood judge the range with its anchor's learnt bias (and the learnt
  // scale) removed: a consistent bias is not NLOS.
  const double d = noise_.correct(r.measurement.anchor_id, r.measurement.range);
  // The range's std: the learnt one (the mixture's LOS std when it is in force), widened where
  // an NLOS model doubts the range.
  const double sigma = (mixture_ ? mixture_->sigma : noise_.sigma()) * std::sqrt(r.variance_scale) *
                       tagScale(r.measurement.tag_id);
  // The pose test: innovation d - d̂ against S = sigma^2 + J P J^T, gated at k sigma. Under the
  // mixture, a range fails when its density falls below the LOS part's at k sqrt(S): a range
  // too short, or longer than the NLOS excess explains.
  const double s = sigma * sigma + state_variance;
  RangeDecision dec;
  dec.t = r.measurement.t;
  dec.anchor_id = r.measurement.anchor_id;
  dec.range = r.measurement.range;
  dec.flag_pose = mixture_ ? mixture_->outside(d - d_hat, std::sqrt(s), params_.nlos_k)
                           : !pose_gate_.accept(d - d_hat, s);
  if (map_) {
    const Eigen::Vector3d tag_world = uwb::tagPosition(e.mean, tag);
    dec.flag_raycast =
        map_->segmentBlocked(tag_world.head<2>(), r.anchor.head<2>(), 1.5 * map_->resolution());
  }
  const bool failed = (params_.nlos == NlosTest::kPose && dec.flag_pose) ||
                      (params_.nlos == NlosTest::kRaycast && dec.flag_raycast);
  epoch_flagged_ += failed;
  if (params_.lost_ranges > 0 && mixture_ && learn_at_lidar_) {
    recent_failed_.push_back(failed);
    if (recent_failed_.size() > static_cast<size_t>(params_.lost_ranges))
      recent_failed_.pop_front();
  }
  // Under the mixture, the chance that this range is NLOS before it is seen (its link's tracked
  // state, or w), and after, at the estimate it was tested against.
  const int tag_id = r.measurement.tag_id;
  double prior = mixture_ ? mixture_->nlos_fraction : 0.0;
  if (mixture_ && nlos_state_.enabled()) {
    prior = nlos_state_.prior(dec.anchor_id, tag_id, dec.t, prior);
    dec.p_nlos = mixture_->nlosPosterior(d - d_hat, std::sqrt(s), prior);
  }
  const bool flagged = failed && !suspended();
  double sig = sigma;
  if (flagged) {
    countRejection(stats, nlos_reason_, dec.anchor_id);
    if (params_.nlos_action == NlosAction::kReject) {
      stats.range_decisions.push_back(dec);
      return;
    }
    sig *= params_.downweight;
  }
  dec.used = true;
  stats.range_decisions.push_back(dec);
  // Under the mixture, this range's likelihood: the mixture at its link's chance of NLOS.
  const RangeMixture link = mixture_ ? mixture_->withNlosFraction(prior) : RangeMixture{};
  // The swarm's fitness weighs the clean ranges at the learnt std: none downweighted, doubted by
  // an NLOS model or of a wider tag.
  if (sig == sigma && r.variance_scale == 1.0 && tagScale(tag_id) == 1.0) {
    used_.push_back({r, link});
    used_.back().range.measurement.range = d;
  }
  const double inv2 = 1.0 / (2.0 * sig * sig);
  const Eigen::Vector3d anchor = r.anchor;
  if (mixture_) {
    const double share = mixture_->weight;
    pf.weight([&](double x, double y, double th) {
      return share * link.logDensity(d - uwb::predictRange({x, y, th}, tag, anchor), sig);
    });
    if (nlos_state_.enabled()) nlos_state_.update(dec.anchor_id, tag_id, dec.t, dec.p_nlos);
    return;
  }
  pf.weight([&](double x, double y, double th) {
    const double h = uwb::predictRange({x, y, th}, tag, anchor);
    return -(d - h) * (d - h) * inv2;  // eq. (26), in logs
  });
}

double UwbRangeMeasurement::addLogLikelihood(double l, double x, double y, double theta) const {
  const double inv2 = 1.0 / (2.0 * noise_.sigma() * noise_.sigma());
  for (const auto& [r, link] : used_) {
    const double h = uwb::predictRange({x, y, theta}, r.measurement.tag_on_robot, r.anchor);
    if (mixture_)
      l += mixture_->weight * link.logDensity(r.measurement.range - h);
    else
      l -= (r.measurement.range - h) * (r.measurement.range - h) * inv2;  // eq. (26), in logs
  }
  return l;
}

// ---------------------------------------------------------------- the range model probe

RangeModelProbe::RangeModelProbe(const EstimatorContext& context)
    : front_(RangeFrontEndParams{}, context.anchors, nullptr, TagUse::kAll, primaryTag(context)) {}

bool RangeModelProbe::take(const Event& event, EstimatorStatistics& stats) {
  auto accepted = acceptRange(front_, event, stats);
  if (accepted) epoch_.push_back(*accepted);
  return accepted.has_value();
}

void RangeModelProbe::endEpoch(const PoseEstimate& estimate) {
  for (const auto& r : epoch_)
    residuals_.emplace_back(
        r.measurement.anchor_id,
        r.measurement.range -
            uwb::predictRange(estimate.pose, r.measurement.tag_on_robot, r.anchor));
  epoch_.clear();
}

void RangeModelProbe::finish(EstimatorStatistics& stats) {
  constexpr size_t kMinResiduals = 100;
  if (residuals_.size() < kMinResiduals) {
    ++stats.events["range_model_too_few_ranges"];
    return;
  }
  // Robust statistics: the median and 1.4826 x the median absolute deviation, or a faulty
  // anchor's gross errors would set the std (the MRPT demo's beacon 1, metres off at times:
  // `lidar-mcl:range_model=1` gives 0.135 m over the whole run, its beacons 0.081-0.247 m).
  const auto robust = [](std::vector<double> v) {
    const double m = medianOf(v);
    for (double& e : v) e = std::abs(e - m);
    return std::pair{m, 1.4826 * medianOf(std::move(v))};
  };
  std::map<int, std::vector<double>> by_anchor;
  std::vector<double> all;
  all.reserve(residuals_.size());
  for (const auto& [anchor, e] : residuals_) {
    by_anchor[anchor].push_back(e);
    all.push_back(e);
  }
  for (auto& [anchor, e] : by_anchor) {
    const auto [bias, sigma] = robust(e);
    stats.estimated_noise[anchor] = {bias, sigma, static_cast<long>(e.size())};
  }
  stats.estimated_range_sigma = robust(std::move(all)).second;
  if (const auto fit = fitRangeMixture(residuals_)) {
    stats.estimated_range_mixture = fit->mixture;
    stats.estimated_range_mixture->weight = independentShare(residuals_);
    ++stats.events["range_mixture_learnt"];
  }
  ++stats.events["range_model_at_filter_pose"];
}

// ---------------------------------------------------------------- the beetle swarm

SwarmStep::SwarmStep(const SwarmPartParams& params) : params_(params) {
  box_ = optim::Box{Eigen::VectorXd(3), Eigen::VectorXd(3)};
  optim::IbasParams ibas;
  ibas.frame_invariant_mutation = true;  // eq. (25) as printed scales with the map coordinates
  ibas.random_tie_direction = false;  // a flat epoch fitness carries no information
  ibas.move_mask = Eigen::Vector3d(1.0, 1.0, params_.move_theta ? 1.0 : 0.0);
  swarm_ = optim::BeetleSwarm(ibas);
}

void SwarmStep::beginEpoch(const ParticleFilter& pf) {
  if (params_.weights == SwarmWeights::kFitness) return;
  prior_log_w_ = pf.particles().log_w;
  if (params_.weights == SwarmWeights::kPosterior) predicted_ = pf.estimate();
}

void SwarmStep::apply(ParticleFilter& pf, const EpochFitness& fitness, double t,
                      EstimatorStatistics& stats) {
  if (!scan_ && params_.epochs == SwarmEpochs::kScans) {
    pf.normalizeAndResample();
    return;
  }
  pf.normalize();
  const double spread = move(pf, fitness);
  char row[64];
  std::snprintf(row, sizeof row, "%.6f,%.5f\n", t, spread);
  spread_log_ += row;
  reweight(pf, fitness, spread, stats);
  pf.normalize();
  if (params_.resample) pf.normalizeAndResample();
}

double SwarmStep::move(ParticleFilter& pf, const EpochFitness& fitness) {
  ParticleSet& ps = pf.particles();
  const auto n = static_cast<Eigen::Index>(ps.size());
  const ParticleEstimate e = pf.estimate();
  positions_.resize(n, 3);  // the heading is always part of the fitness; move_theta moves it
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto u = static_cast<size_t>(i);
    positions_(i, 0) = ps.x[u];
    positions_(i, 1) = ps.y[u];
    // Headings unwrapped around the mean, so the search box does not straddle +-pi.
    positions_(i, 2) = e.mean.z() + wrapAngle(ps.theta[u] - e.mean.z());
  }
  // Search box: the cloud's extent, at least 0.3 m (0.2 rad) around the mean.
  for (Eigen::Index c = 0; c < 3; ++c) {
    const double half =
        std::max(3.0 * std::sqrt(std::max(e.covariance(c, c), 0.0)), c == 2 ? 0.2 : 0.3);
    box_.lo(c) = std::min(e.mean(c) - half, positions_.col(c).minCoeff());
    box_.hi(c) = std::max(e.mean(c) + half, positions_.col(c).maxCoeff());
  }
  const optim::Objective objective = [&](const Eigen::Ref<const Eigen::VectorXd>& q) {
    return fitness(q(0), q(1), q(2));
  };
  long evals = 0;
  double best = 0.0;
  if (params_.weights == SwarmWeights::kPosterior) start_ = positions_;
  // The initial step, and the antenna it starts with: the one given, or the search box's planar
  // width.
  const double step =
      params_.step.value.value_or(0.5 * ((box_.hi(0) - box_.lo(0)) + (box_.hi(1) - box_.lo(1))));
  swarm_.setAntenna(step);
  swarm_.maximize(positions_, objective, box_, params_.iterations, step, pf.rng(), &best, &evals);
  double mx = 0, my = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto u = static_cast<size_t>(i);
    ps.x[u] = positions_(i, 0);
    ps.y[u] = positions_(i, 1);
    ps.theta[u] = wrapAngle(positions_(i, 2));
    mx += ps.x[u] / n;
    my += ps.y[u] / n;
  }
  double var = 0;
  for (size_t i = 0; i < ps.size(); ++i)
    var += (std::pow(ps.x[i] - mx, 2) + std::pow(ps.y[i] - my, 2)) / n;
  return std::sqrt(var);
}

void SwarmStep::reweight(ParticleFilter& pf, const EpochFitness& fitness, double spread,
                         EstimatorStatistics& stats) {
  ParticleSet& ps = pf.particles();
  // Eq. (28): the weights are the fitness at the moved positions, normalised. The swarm has
  // already evaluated it there; only particles moved again by a diversity injection need it anew.
  const Eigen::VectorXd& fitness_at = swarm_.values();
  if (spread < params_.min_spread) {
    // Diversity: a collapsed swarm would freeze the estimate.
    std::normal_distribution<double> g(0.0, params_.min_spread);
    for (size_t i = 0; i < ps.size(); ++i) {
      ps.x[i] += g(pf.rng());
      ps.y[i] += g(pf.rng());
      ps.log_w[i] = fitness(ps.x[i], ps.y[i], ps.theta[i]);
    }
    ++stats.events["swarm_diversity_injection"];
  } else {
    for (size_t i = 0; i < ps.size(); ++i) ps.log_w[i] = fitness_at(static_cast<Eigen::Index>(i));
  }
  if (params_.weights == SwarmWeights::kFitness) return;
  // Sequential importance weights: the weight each particle carried into this epoch (its
  // history since the last resampling) times the epoch's likelihood.
  for (size_t i = 0; i < ps.size(); ++i) ps.log_w[i] += prior_log_w_[i];
  if (params_.weights != SwarmWeights::kPosterior) return;
  // And the predicted density's ratio between where the swarm left each particle and where the
  // motion model put it (the heading only when the swarm moves it: otherwise its rows of the
  // information matrix stay zero).
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  if (params_.move_theta)
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
    ps.log_w[i] +=
        offset(start_(r, 0), start_(r, 1), start_(r, 2)) - offset(ps.x[i], ps.y[i], ps.theta[i]);
  }
}

void SwarmStep::addArtifacts(std::vector<std::pair<std::string, std::string>>& out) const {
  if (!spread_log_.empty()) out.emplace_back("swarm_spread.csv", "t,spread_xy\n" + spread_log_);
}

}  // namespace uwbloc::loc
