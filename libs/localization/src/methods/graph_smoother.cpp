#include "uwbloc/localization/methods/graph_smoother.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "uwbloc/localization/fix_continuity.hpp"
#include "uwbloc/localization/kalman/kalman.hpp"
#include "uwbloc/localization/lidar/landmarks.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::loc {

namespace {
/// bias=auto judges an anchor from at least this many ranges.
constexpr long kMinRangesForBias = 20;
/// sigma=auto stops re-estimating once the std moves by less than this fraction: each round
/// costs a marginal-covariance computation, and the last percents change no pose noticeably.
constexpr double kSettled = 0.05;
/// scale=auto never takes a scale beyond this fraction, twice the largest seen on a real
/// recording (Plaza2's old radios, +7 %): a solve that finds one has taken another error for
/// it (the simulated room's three anchors each 1 m long read as +18 % over 60 s, 3 m as -48 %).
constexpr double kMaxPlausibleScale = 0.15;
/// bias=auto drops biases that widen the anchors' pooled residual spread by more than this
/// fraction (pooledSpread).
constexpr double kSpreadGrowth = 0.05;

/// The anchors' residual spreads about their own medians, pooled (root mean square weighted by
/// the range counts).
double pooledSpread(const graph::RangeGraph& g) {
  double sum = 0.0;
  long n = 0;
  for (const auto& a : g.anchorResiduals()) {
    sum += static_cast<double>(a.ranges) * a.robust_sigma * a.robust_sigma;
    n += a.ranges;
  }
  return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : 0.0;
}

/// Whether the solve in `g` has widened the pooled spread from `before` by more than
/// kSpreadGrowth.
bool widensSpread(const graph::RangeGraph& g, double before) {
  return pooledSpread(g) > before * (1.0 + kSpreadGrowth);
}
/// Each variance re-estimate needs the marginal covariances of every pose, which grows about
/// with the square of their number (CARMEN intel with simulated UWB, 9 721 poses: about 2 min);
/// larger graphs keep the starting std and say so (event noise_estimate_skipped_large_graph).
constexpr size_t kMaxPosesForNoiseEstimate = 20000;
// The smallest factor on the odometry model's std that odom_noise=auto tries.
constexpr double kMinOdometryFactor = 1.0 / 64.0;
// Its cross-validation's test: blocks of consecutive held-out ranges, at least this many, and the
// standard errors a better factor must gain by.
constexpr size_t kCvBlock = 50;
constexpr size_t kCvMinBlocks = 5;
constexpr double kCvStandardErrors = 2.0;
/// nlos_mixture: at most this many fits of the mixture, each followed by a solve
constexpr int kMixtureRounds = 3;
/// motion=cv with q=auto: the white-acceleration spectral density the estimate starts from
/// [m^2/s^3] (a walking pace's turns; the variance components move it to the data's).
constexpr double kStartAccelPsd = 1.0;
/// motion=cv: ranges closer in time than this share a vertex [s].
constexpr double kSameVertex = 1e-3;

// The graph's anchors are vertices (fixed, or calibrated within the run): a mobile node, whose
// position moves, is not one of them; ranges to it count as unknown_anchor.
RangeFrontEndParams fixedAnchorsOnly(RangeFrontEndParams p) {
  p.mobile_anchors = false;
  return p;
}

}  // namespace

GraphSmoother::GraphSmoother(const GraphSmootherParams& params, const EstimatorContext& context)
    : UwbEstimator(fixedAnchorsOnly(params.front), context,
                   params.motion == GraphMotion::kConstantVelocity ? TagUse::kPrimary
                                                                  : TagUse::kAll),
      params_(params),
      context_(context) {
  if (constantVelocity() && !params_.front_end.empty())
    throw ParamError("motion=cv smooths the ranges alone: it takes no front end");
  if (!context.initial_pose && !constantVelocity())
    throw ParamError("graph smoothing needs a start pose (the dataset's ground truth)");
  if (!params_.front_end.empty()) {
    // The spec's own ',' separates graph parameters, so front-end parameters use ';'.
    std::string spec = params_.front_end;
    std::replace(spec.begin(), spec.end(), ';', ',');
    front_ = Registry::builtin().create(spec, context);
    if (params_.icp) icp_ = Registry::builtin().create("lidar-icp", context);
  }
}

graph::RangeGraphParams GraphSmoother::graphParams() const {
  graph::RangeGraphParams p;
  p.range_sigma = params_.front.sigmaValue();
  p.loss = params_.loss;
  p.loss_scale = params_.loss_scale;
  p.estimate_bias = params_.bias == BiasMode::kOn;
  p.estimate_scale = params_.scale == BiasMode::kOn;
  p.estimate_anchors = params_.estimate_anchors;
  p.anchor_prior_sigma = params_.anchor_prior;
  p.max_iterations = params_.iterations;
  p.accel_psd = params_.accel_psd.value.value_or(kStartAccelPsd);
  p.odometry_sigma_factor = params_.odom_noise.value.value_or(1.0);
  return p;
}

Eigen::Vector3d GraphSmoother::priorSigma(const PoseEstimate& e) const {
  return {std::max(std::sqrt(std::max(e.covariance(0, 0), 0.0)), params_.prior_min_xy),
          std::max(std::sqrt(std::max(e.covariance(1, 1), 0.0)), params_.prior_min_xy),
          std::max(std::sqrt(std::max(e.covariance(2, 2), 0.0)), params_.prior_min_theta)};
}

std::optional<PoseEstimate> GraphSmoother::solveWindow() {
  graph::RangeGraph g;
  g.setAnchors(context_.anchors);
  for (size_t i = 0; i < window_.size(); ++i) {
    const auto& w = window_[i];
    const int v = g.addPose(w.pose);
    g.addPosePrior(v, w.front.pose, priorSigma(w.front));
    if (i > 0) {
      g.addOdometry(v - 1, v, w.odometry_before, odometrySigma(w.odometry_before));
    }
    for (const auto& r : w.ranges)
      g.addRange(v, r.measurement.anchor_id, r.measurement.range, r.measurement.tag_on_robot,
                 r.variance_scale, r.measurement.tag_id);
  }
  graph::RangeGraphParams p = graphParams();
  p.max_iterations = std::min(p.max_iterations, 20);
  g.build(p);
  if (window_.size() > 1) g.holdPose(0);  // the window's oldest vertex anchors it
  if (!g.solve().usable) {
    countRejection("graph_not_usable");
    return std::nullopt;
  }
  for (size_t i = 0; i < window_.size(); ++i) window_[i].pose = g.pose(i);
  // The newest pose at once, or (fixed lag) the second-oldest once the window is full: the
  // oldest is held, so this is the last solve that can change it.
  size_t k = window_.size() - 1;
  if (params_.lagged) {
    if (window_.size() < static_cast<size_t>(params_.window) || window_.size() < 2)
      return std::nullopt;
    k = 1;
  }
  if (window_[k].front.t <= last_output_t_) return std::nullopt;
  PoseEstimate out = window_[k].front;
  out.pose = window_[k].pose;
  last_output_t_ = out.t;
  return out;
}

std::optional<PoseEstimate> GraphSmoother::doProcess(const Event& event) {
  if (!started_) {
    first_t_ = eventTime(event);
    started_ = true;
  }
  std::optional<PoseEstimate> out;
  std::optional<PoseEstimate> front_estimate;
  if (icp_) {
    if (auto e = icp_->process(event)) icp_poses_.push_back(*e);
  }
  if (front_) {
    if (auto e = front_->process(event)) {
      if (!online()) front_estimates_.push_back(*e);  // kept for the batch solve only
      front_estimate = e;
    }
  }
  if (front_estimate && online()) out = addWindowVertex(*front_estimate);
  if (const auto* scan = std::get_if<LaserScan>(&event)) {
    if (front_ && params_.landmarks && !online()) {
      const LandmarkExtractionParams ex;
      corners_.push_back({scan->t, extractCorners(extractLines(*scan, ex), ex)});
    }
    return out;
  }
  if (const auto* odo = std::get_if<OdometryIncrement>(&event)) {
    if (constantVelocity()) return out;  // the ranges alone
    if (!odo->delta.allFinite()) {
      countRejection("non_finite_odometry");
      return out;
    }
    if (online())
      odometry_pending_.push_back(*odo);
    else
      odometry_.push_back(*odo);
    return out;
  }
  if (const auto accepted = acceptRange(event)) {
    if (!online())
      ranges_.push_back(*accepted);
    else
      ranges_pending_.push_back(*accepted);
  }
  return out;
}

// A new vertex at the front end's estimate, with the odometry and the ranges up to its time that
// are not yet on a vertex: sliced by time, because the front end may hand estimates out late
// (a particle filter learning its range model). Odometry stamped with the estimate's own time is
// the motion that led there (MRPT rawlogs store the action before the observations).
std::optional<PoseEstimate> GraphSmoother::addWindowVertex(const PoseEstimate& e) {
  WindowVertex v{e, e.pose, Eigen::Vector3d::Zero(), {}};
  while (!odometry_pending_.empty() && odometry_pending_.front().t <= e.t) {
    v.odometry_before = composePose(v.odometry_before, odometry_pending_.front().delta);
    odometry_pending_.pop_front();
  }
  while (!ranges_pending_.empty() && ranges_pending_.front().measurement.t <= e.t) {
    v.ranges.push_back(ranges_pending_.front());
    ranges_pending_.pop_front();
  }
  window_.push_back(std::move(v));
  if (window_.size() > static_cast<size_t>(params_.window)) window_.erase(window_.begin());
  return solveWindow();
}

void GraphSmoother::mergeFrontStatistics() {
  const EstimatorStatistics& f = front_->statistics();
  for (const auto& [reason, count] : f.rejected) stats_.rejected["front:" + reason] += count;
  for (const auto& [anchor, reasons] : f.rejected_by_anchor)
    for (const auto& [reason, count] : reasons)
      stats_.rejected_by_anchor[anchor]["front:" + reason] += count;
  stats_.range_decisions.insert(stats_.range_decisions.end(), f.range_decisions.begin(),
                                f.range_decisions.end());
  stats_.resets += f.resets;
  for (const auto& [name, count] : f.events) stats_.events["front:" + name] += count;
}

// The rest of the online (fixed-lag) run: the front end's last estimates, then the poses still
// inside the last window.
std::vector<PoseEstimate> GraphSmoother::finishWindow() {
  std::vector<PoseEstimate> out;
  auto rest = front_->finishAll();
  mergeFrontStatistics();
  for (auto& e : rest)
    if (auto w = addWindowVertex(e)) out.push_back(*w);
  // The poses still inside the last window.
  for (const auto& w : window_)
    if (w.front.t > last_output_t_) {
      PoseEstimate e = w.front;
      e.pose = w.pose;
      out.push_back(e);
      last_output_t_ = e.t;
    }
  return out;
}

Eigen::Vector3d GraphSmoother::odometrySigma(const Eigen::Vector3d& d) const {
  const double sxy = params_.odom_sigma_xy + params_.odom_sigma_xy_per_m * d.head<2>().norm();
  const double sth = params_.odom_sigma_theta + params_.odom_sigma_theta_per_rad * std::abs(d.z());
  return Eigen::Vector3d(sxy, sxy, sth);
}

// Vertices: the front end's estimates (with their priors and the odometry between them), or one
// per odometry increment (dead reckoning from the start pose). Returns each vertex's time.
std::vector<double> GraphSmoother::addPoseVertices(graph::RangeGraph& g) const {
  if (constantVelocity()) return addRangeVertices(g);
  std::vector<double> times;
  if (front_) {
    size_t k = 0;
    for (size_t i = 0; i < front_estimates_.size(); ++i) {
      const auto& e = front_estimates_[i];
      const int v = g.addPose(e.pose);
      times.push_back(e.t);
      const Eigen::Vector3d sigma(
          std::max(std::sqrt(std::max(e.covariance(0, 0), 0.0)), params_.prior_min_xy),
          std::max(std::sqrt(std::max(e.covariance(1, 1), 0.0)), params_.prior_min_xy),
          std::max(std::sqrt(std::max(e.covariance(2, 2), 0.0)), params_.prior_min_theta));
      g.addPosePrior(v, e.pose, sigma);
      // The odometry between the previous vertex and this one.
      Eigen::Vector3d delta = Eigen::Vector3d::Zero();
      bool moved = false;
      while (k < odometry_.size() && odometry_[k].t <= e.t) {
        if (i > 0 && odometry_[k].t > times[i - 1]) {
          delta = composePose(delta, odometry_[k].delta);
          moved = true;
        }
        ++k;
      }
      if (i > 0 && moved) g.addOdometry(v - 1, v, delta, odometrySigma(delta));
    }
  } else {
    Eigen::Vector3d pose = *context_.initial_pose;
    g.addPose(pose);
    times.push_back(first_t_);
    for (const auto& o : odometry_) {
      pose = composePose(pose, o.delta);
      const int v = g.addPose(pose);
      times.push_back(o.t);
      g.addOdometry(v - 1, v, o.delta, odometrySigma(o.delta));
    }
  }
  return times;
}

std::vector<double> GraphSmoother::addRangeVertices(graph::RangeGraph& g) const {
  std::vector<double> times;
  for (const auto& r : ranges_)
    if (times.empty() || r.measurement.t - times.back() > kSameVertex)
      times.push_back(r.measurement.t);
  if (times.empty()) return times;
  // Where the vertices start: the per-epoch Gauss-Newton fixes, checked for continuity from the
  // start pose (fix_continuity.hpp: a fix the tag cannot have reached is replaced by the
  // reachable position that most ranges fit), each replaced by the median of it and its four
  // neighbours per axis, interpolated in time; before the first and after the last, the nearest.
  std::vector<double> fix_t;
  std::vector<Eigen::Vector2d> fix_xy;
  EpochBuffer epochs(AutoDouble{});
  FixContinuityParams continuity_params{params_.front.iq_max_speed, params_.front.iq_floor};
  continuity_params.track = false;  // every method's learning start: the speed bound alone
  FixContinuity continuity(continuity_params);
  if (context_.initial_pose && !ranges_.empty())
    continuity.seed(context_.initial_time,
                    tagFromRobot(*context_.initial_pose, ranges_.front().measurement.tag_on_robot));
  auto gaussNewton = [](const std::vector<uwb::PlanarRange>& planar) {
    return uwb::solveGaussNewton(planar);
  };
  auto addFix = [&](const std::optional<std::vector<AcceptedRange>>& epoch) {
    if (!epoch) return;
    const auto planar = toPlanar(*epoch, params_.front.sigmaValue());
    const uwb::Fix f = uwb::solveGaussNewton(planar);
    if (!f.ok() || !f.position.allFinite()) return;
    const auto checked = continuity.check(epochTime(*epoch), f, planar, gaussNewton);
    if (checked.fix) {
      fix_t.push_back(epochTime(*epoch));
      fix_xy.push_back(checked.fix->position);
    }
  };
  for (const auto& r : ranges_) addFix(epochs.add(r));
  addFix(epochs.flush());
  if (fix_xy.empty()) {
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const auto& a : context_.anchors) centre += a.position.head<2>();
    fix_t.push_back(times.front());
    fix_xy.push_back(context_.initial_pose ? Eigen::Vector2d(context_.initial_pose->head<2>())
                                           : Eigen::Vector2d(centre / std::max<size_t>(
                                                                          context_.anchors.size(),
                                                                          1)));
  }
  std::vector<Eigen::Vector2d> smooth(fix_xy.size());
  for (size_t i = 0; i < fix_xy.size(); ++i) {
    const size_t lo = i >= 2 ? i - 2 : 0, hi = std::min(fix_xy.size(), i + 3);
    for (int axis = 0; axis < 2; ++axis) {
      std::vector<double> v;
      for (size_t k = lo; k < hi; ++k) v.push_back(fix_xy[k](axis));
      smooth[i](axis) = medianOf(std::move(v));
    }
  }
  size_t k = 0;
  for (size_t i = 0; i < times.size(); ++i) {
    const double t = times[i];
    while (k + 1 < fix_t.size() && fix_t[k + 1] <= t) ++k;
    Eigen::Vector2d xy = smooth[k];
    if (k + 1 < fix_t.size() && t > fix_t[k]) {
      const double f = (t - fix_t[k]) / (fix_t[k + 1] - fix_t[k]);
      xy = (1.0 - f) * smooth[k] + f * smooth[k + 1];
    }
    // The vertex is the tag's position (ranges are added without the lever arm); its heading
    // enters no edge, so a prior holds it.
    const int v = g.addPose(Eigen::Vector3d(xy.x(), xy.y(), 0.0));
    g.addPosePrior(v, Eigen::Vector3d(xy.x(), xy.y(), 0.0), Eigen::Vector3d(1e4, 1e4, 1.0));
    if (i >= 2) g.addConstantVelocity(v - 2, v - 1, v, times[i - 1] - times[i - 2], t - times[i - 1]);
  }
  return times;
}

std::vector<PoseEstimate> GraphSmoother::trackPoses(const graph::RangeGraph& g,
                                                    const std::vector<double>& times) const {
  const Eigen::Vector3d tag =
      ranges_.empty() ? Eigen::Vector3d::Zero() : ranges_.front().measurement.tag_on_robot;
  HeadingFromMotion heading;
  if (context_.initial_pose) heading.setHeading(context_.initial_pose->z());
  std::vector<PoseEstimate> out;
  for (size_t i = 0; i < g.poses(); ++i) {
    const size_t a = i > 0 ? i - 1 : i, b = std::min(i + 1, g.poses() - 1);
    if (b > a) heading.update((g.pose(b) - g.pose(a)).head<2>() / (times[b] - times[a]));
    out.push_back(kalman::tagTrackPose(times[i], g.pose(i).head<2>(), Eigen::Matrix2d::Zero(),
                                       tag, heading.heading()));
  }
  return out;
}

// Scan matching between consecutive vertices (where both have an ICP pose at their time).
void GraphSmoother::addIcpEdges(graph::RangeGraph& g, const std::vector<double>& times) const {
  auto icpAt = [&](double t) -> const PoseEstimate* {
    auto it = std::lower_bound(icp_poses_.begin(), icp_poses_.end(), t,
                               [](const PoseEstimate& p, double v) { return p.t < v - 1e-9; });
    return it != icp_poses_.end() && std::abs(it->t - t) < 1e-6 ? &*it : nullptr;
  };
  for (size_t i = 1; i < times.size(); ++i) {
    const auto* a = icpAt(times[i - 1]);
    const auto* b = icpAt(times[i]);
    if (a && b)
      g.addOdometry(
          static_cast<int>(i - 1), static_cast<int>(i), relativePose(a->pose, b->pose),
          Eigen::Vector3d(params_.icp_sigma_xy, params_.icp_sigma_xy, params_.icp_sigma_theta));
  }
}

// LiDAR corners: associated from the front end's poses, then landmark vertices and edges.
void GraphSmoother::addLandmarks(graph::RangeGraph& g, const std::vector<double>& times) const {
  LandmarkMap map;
  const Eigen::Matrix2d r =
      Eigen::Matrix2d::Identity() * params_.landmark_sigma * params_.landmark_sigma;
  struct Obs {
    int vertex, landmark;
    Eigen::Vector2d z;
  };
  std::vector<Obs> obs;
  size_t v = 0;
  for (const auto& sc : corners_) {
    while (v + 1 < times.size() && times[v] < sc.t - 1e-9) ++v;
    if (std::abs(times[v] - sc.t) > 1e-6) continue;  // a scan without a front-end estimate
    const auto& e = front_estimates_[v];
    for (const auto& c : sc.corners)
      obs.push_back({static_cast<int>(v), map.integrate(e.pose, e.covariance, c, r), c});
  }
  std::vector<int> vertex_of(map.landmarks().size(), -1);
  for (const auto& o : obs) {
    const auto& lm = map.landmarks()[static_cast<size_t>(o.landmark)];
    if (lm.observations < params_.landmark_min_obs) continue;
    if (vertex_of[static_cast<size_t>(o.landmark)] < 0)
      vertex_of[static_cast<size_t>(o.landmark)] = g.addLandmark(lm.position);
    g.addLandmarkObservation(o.vertex, vertex_of[static_cast<size_t>(o.landmark)], o.z,
                             params_.landmark_sigma);
  }
}

// Each range constrains the vertex nearest to it in time.
void GraphSmoother::addRanges(graph::RangeGraph& g, const std::vector<double>& times) {
  range_times_.clear();
  for (const auto& r : ranges_) {
    const auto it = std::lower_bound(times.begin(), times.end(), r.measurement.t);
    size_t i = static_cast<size_t>(it - times.begin());
    if (i == times.size() || (i > 0 && r.measurement.t - times[i - 1] < times[i] - r.measurement.t))
      --i;
    if (std::abs(times[i] - r.measurement.t) > 1.0) {
      countRejection("range_far_from_any_pose", r.measurement.anchor_id);
      continue;
    }
    // motion=cv: the vertex is the tag itself.
    const Eigen::Vector3d tag =
        constantVelocity() ? Eigen::Vector3d(0.0, 0.0, r.measurement.tag_on_robot.z())
                           : r.measurement.tag_on_robot;
    g.addRange(static_cast<int>(i), r.measurement.anchor_id, r.measurement.range, tag,
               r.variance_scale, r.measurement.tag_id);
    range_times_.push_back(r.measurement.t);
  }
}

// odom_noise=auto. Measured with `uwbloc benchmark --seeds 1 -m graph-uwb-odom` (factor; 2D RMSE
// before -> after): the simulated rooms, whose odometry is 0.02 m per metre at 10-30 Hz, 1/16 to
// 1/8 (pfibas_room 0.149 -> 0.034 m, agv_room 0.101 -> 0.037, plate 0.057 -> 0.027); the
// CARMEN logs with simulated anchors (intel 0.435 -> 0.397, aces 0.344 -> 0.308); Plaza2,
// whose odometry errs systematically (distances 3.75 % short), and the MRPT demo keep the model.
// The training solves hold the biases and the scale (solved with every anchor) so that only
// the path answers for the held-out ranges, and the loss's scale is the residuals' own spread.
// Without the test against chance, the demo took 1/2 (0.115 -> 0.121 m) and the loosest factors
// (x2, x4) won on the simulated greenhouses, whose ranges carry 0.5-1 m noise (R3 0.203 ->
// 0.253 m): so the model, already loose, is only tightened. Where several anchors are NLOS
// together (the simulated office) the held-out ranges share the others' pull and the test stops
// early (1/2: 0.221 -> 0.200 m, where 1/64 gives 0.100 m; under the NLOS mixture 1/2 still,
// 0.075 m, where 1/64 gives 0.046 m). Scoring the held-out ranges by the mixture's density
// instead (about the held bias, no median) took the office to 1/4, 0.066 m, but plate 0.013 ->
// 0.017 and pfibas_room 0.020 -> 0.022 m. Weighing each one's loss by its LOS probability, at
// the mixture's LOS std, and halving on while the mean loss falls took it (with each link's NLOS
// state) from 1 to 1/4, 0.055 -> 0.044 m, and moved no other benchmark cell; either change
// alone leaves it at 1.
double GraphSmoother::crossValidatedOdometryFactor(graph::RangeGraph& g,
                                                   const graph::RangeGraphParams& p) {
  const double start = p.odometry_sigma_factor;
  // The anchors with ranges enough to score.
  std::map<int, long> count;
  for (const auto& [id, e] : g.rangeResiduals()) ++count[id];
  std::vector<int> held_out;  // anchor indices
  for (size_t a = 0; a < g.anchors().size(); ++a)
    if (count[g.anchors()[a].id] >= kMinRangesForBias) held_out.push_back(static_cast<int>(a));
  if (held_out.size() < 2) return start;
  const auto solved = g.values();
  // The loss's scale: the residuals' own spread about each anchor's median (the range std in `p`
  // may still count the biases' part of the error, and a wide scale hides every difference);
  // under the NLOS mixture, its LOS std (the spread counts the NLOS excess).
  const double spread = pooledSpread(g);
  const double c = p.loss_scale * (p.range_mixture ? p.range_mixture->sigma
                                   : spread > 0.0  ? spread
                                                   : p.range_sigma);
  // Under the mixture each range's loss weighs its LOS probability, read from the solution with
  // every anchor (the mixture's posterior at its fraction): a range through a wall says how far
  // the wall is, not where the path is.
  std::map<int, std::vector<double>> los_weight;  // anchor id -> weights, in time
  for (const auto& [id, e] : g.rangeResidualsLessBias())
    los_weight[id].push_back(
        p.range_mixture ? 1.0 - p.range_mixture->nlosPosterior(e, p.range_mixture->sigma,
                                                               p.range_mixture->nlos_fraction)
                        : 1.0);
  // Each held-out range's robust loss, in a fixed order (anchor by anchor, in time).
  auto losses = [&](double factor) -> std::optional<std::vector<double>> {
    graph::RangeGraphParams q = p;
    q.odometry_sigma_factor = factor;
    std::vector<double> out;
    for (const int a : held_out) {
      q.left_out_anchor = a;
      g.restore(solved);
      g.build(q);
      g.holdRangeModel();
      ++stats_.events["odometry_noise_cv_solves"];
      if (!g.solve().usable) return std::nullopt;
      std::vector<double> e;
      for (const auto& [id, r] : g.rangeResiduals())
        if (id == g.anchors()[static_cast<size_t>(a)].id) e.push_back(r);
      const double m = medianOf(e);
      const auto& w = los_weight[g.anchors()[static_cast<size_t>(a)].id];
      for (size_t i = 0; i < e.size(); ++i)
        out.push_back(w[i] * std::log1p((e[i] - m) * (e[i] - m) / (c * c)));
    }
    return out;
  };
  // Whether `candidate` predicts the held-out ranges better than `incumbent` beyond chance: the
  // mean paired difference exceeds kCvStandardErrors standard errors, taken over blocks of
  // kCvBlock consecutive ranges (a range's error is correlated with its neighbours').
  auto better = [](const std::vector<double>& candidate, const std::vector<double>& incumbent) {
    const size_t blocks = candidate.size() / kCvBlock;
    if (blocks < kCvMinBlocks) return false;
    double sum = 0.0, sum_sq = 0.0;  // of the blocks' mean differences
    for (size_t b = 0; b < blocks; ++b) {
      double d = 0.0;
      for (size_t i = b * kCvBlock; i < (b + 1) * kCvBlock; ++i) d += incumbent[i] - candidate[i];
      d /= static_cast<double>(kCvBlock);
      sum += d;
      sum_sq += d * d;
    }
    const double n = static_cast<double>(blocks);
    const double gain = sum / n;
    const double se = std::sqrt(std::max(sum_sq / n - gain * gain, 0.0) / (n - 1.0));
    return gain > kCvStandardErrors * se;
  };
  auto mean = [](const std::vector<double>& v) {
    return v.empty() ? 0.0
                     : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
  };
  double best_factor = start;
  auto best = losses(start);
  if (!best) ++stats_.events["odometry_noise_cv_failed"];
  // Halving goes on while the mean loss falls, and a factor is taken when it beats the one
  // taken before it beyond chance: the gain of one halving may be within chance where that of
  // two is not.
  double last_mean = best ? mean(*best) : 0.0;
  for (double f = start / 2.0; best && f >= kMinOdometryFactor; f /= 2.0) {
    auto candidate = losses(f);
    if (!candidate) break;
    const double m = mean(*candidate);
    if (better(*candidate, *best)) {
      best = std::move(candidate);
      best_factor = f;
    } else if (m >= last_mean) {
      break;
    }
    last_mean = m;
  }
  g.restore(solved);
  g.build(p);
  return best_factor;
}

bool GraphSmoother::solveOnce(graph::RangeGraph& g, const graph::RangeGraphParams& p) {
  g.build(p);
  if (g.solve().usable) return true;
  countRejection("graph_not_usable");
  return false;
}

// Several biases free cost accuracy even when each is right: the path's offset and the biases
// are told apart only by the geometry's change along the run. Simulated PF-IBAS room, every
// range 1 m long (`uwbloc sensitivity`): 0.015 m with a bias per anchor, 0.011 m with one
// shared, as with the true ranges. The test is the information criterion at the per-anchor
// solution's std (the std of the solve may still count the biases: learnt before them, it
// reads 0.79 m there, which would let any pattern of biases pass for one); the std and the
// model's other values are left as they were.
bool GraphSmoother::preferCommonBias(graph::RangeGraph& g, graph::RangeGraphParams& p) {
  if (!p.estimate_bias || p.common_bias || g.poses() > kMaxPosesForNoiseEstimate) return false;
  int anchors = 0;
  for (const auto& a : g.anchorResiduals()) anchors += a.ranges > 0 ? 1 : 0;
  if (anchors < 2) return false;
  const auto sigma = g.estimateVarianceComponents().range_sigma;
  if (!sigma) return false;
  const auto per_anchor = g.values();
  graph::RangeGraphParams test = p;
  test.range_sigma = *sigma;
  g.build(test);
  const auto separate = g.solve();
  test.common_bias = true;
  g.build(test);
  const auto shared = g.solve();
  const double penalty =
      (anchors - 1) * std::log(static_cast<double>(std::max<size_t>(g.ranges(), 2)));
  const bool stands =
      separate.usable && shared.usable && 2.0 * (shared.final_cost - separate.final_cost) < penalty;
  g.restore(per_anchor);
  if (stands) {
    p.common_bias = true;
    if (solveOnce(g, p)) {
      ++stats_.events["range_bias_common"];
      return true;
    }
    p.common_bias = false;  // (the per-anchor solution and its model stand)
    g.restore(per_anchor);
  }
  g.build(p);
  return false;
}

// sigma=auto: Helmert variance-component estimation of the range std, alternated with solves
// until it settles (the odometry model is not scaled with it: scaling both groups lets the path
// absorb slow range errors; odom_noise=auto learns its factor at the end, by cross-validation). It
// runs without biases: the std it finds then counts the slow, per-anchor part of the error too,
// which a bias removes only on average. bias=auto then frees the biases when an anchor's offset
// (range minus the solved distance) stands out in both halves of the run (biasStandsOut), and
// solves once more. The test reads the solution without biases, in which the path absorbs part of a
// bias on one anchor among few (a 1 m bias on one of three anchors shows as +0.16 m): such a bias
// can go unseen (`uwbloc sensitivity`).
void GraphSmoother::solveBatch(graph::RangeGraph& g) {
  graph::RangeGraphParams p = graphParams();
  bool auto_sigma = params_.front.sigma.isAuto();
  if (auto_sigma && front_ && front_->statistics().estimated_range_sigma) {
    // The front end learnt the std already (a particle filter's batch start): no covariances
    // over its many vertices.
    p.range_sigma = *front_->statistics().estimated_range_sigma;
    stats_.estimated_range_sigma = p.range_sigma;
    auto_sigma = false;
  }
  bool auto_q = constantVelocity() && params_.accel_psd.isAuto();
  if ((auto_sigma || auto_q) && g.poses() > kMaxPosesForNoiseEstimate) {
    ++stats_.events["noise_estimate_skipped_large_graph"];
    auto_sigma = auto_q = false;
  }
  if (auto_sigma || params_.bias == BiasMode::kAuto) p.estimate_bias = false;
  if (auto_sigma || params_.scale == BiasMode::kAuto) p.estimate_scale = false;
  const auto start_values = g.values();
  if (!solveOnce(g, p)) return;
  // Variance-component rounds (the range std, and motion=cv's q), each followed by a re-solve;
  // false when a solve failed.
  auto estimateSigma = [&]() {
    for (int round = 0; round < params_.noise_rounds; ++round) {
      const auto estimate = g.estimateVarianceComponents();
      ++stats_.events["noise_rounds"];
      if ((auto_sigma && !estimate.range_sigma) || (auto_q && !estimate.accel_psd)) {
        ++stats_.events["noise_estimate_failed"];
        break;
      }
      bool settled = true;
      if (auto_sigma) {
        const double sigma = std::clamp(*estimate.range_sigma, 1e-3, 1e3);
        settled = std::abs(sigma / p.range_sigma - 1.0) < kSettled;
        p.range_sigma = sigma;
      }
      if (auto_q) {
        const double q = std::clamp(*estimate.accel_psd, 1e-4, 1e4);
        settled = settled && std::abs(q / p.accel_psd - 1.0) < kSettled;
        p.accel_psd = q;
      }
      if (settled) break;
      if (!solveOnce(g, p)) return false;
    }
    if (auto_sigma) stats_.estimated_range_sigma = p.range_sigma;
    if (auto_q) stats_.estimated_accel_psd = p.accel_psd;
    return true;
  };
  if ((auto_sigma || auto_q) && !estimateSigma()) return;
  // Back to an earlier solution and its parameters (a trial that did not stand).
  auto revert = [&](const graph::RangeGraph::Values& values, const graph::RangeGraphParams& to) {
    p = to;
    g.restore(values);
    g.build(p);
  };
  // A scale, unlike a bias, is a deterministic error of the whole model: once it is solved, the
  // std is estimated again without it (on Plaza2 the ranges read 6.9 % long; the std falls from
  // 3.2 m, which counted that error, to about 0.6 m).
  const bool scale_was_on = p.estimate_scale;
  bool biases_over_scale = false;  // the biases were taken instead of a scale
  if (constantVelocity() && params_.scale == BiasMode::kAuto) {
    // Without odometry the path bends to take up most of a scale's slope (Plaza2: 7 % long
    // ranges leave a slope of 0.3 % once solved without it), and the solve without a scale
    // ends far from the one with it (Plaza2: range std 2.4 m against 0.58 m). So the noise is
    // learnt a second time from the start with the scale free, and the scale stays when it
    // explains a quarter of the residuals' variance (scaleExplains on the two stds).
    const auto without = g.values();
    const graph::RangeGraphParams p_without = p;
    const auto sigma_without = g.estimateVarianceComponents().range_sigma;
    g.restore(start_values);
    p.estimate_scale = true;
    bool stands = solveOnce(g, p) && (!(auto_sigma || auto_q) || estimateSigma());
    const auto sigma_with = stands ? g.estimateVarianceComponents().range_sigma : std::nullopt;
    const bool explains = sigma_without && sigma_with && scaleExplains(*sigma_without, *sigma_with);
    const bool plausible = std::abs(g.scale()) <= kMaxPlausibleScale;
    stands = explains && plausible;
    if (explains && auto_sigma && params_.bias == BiasMode::kAuto && params_.bias_trial) {
      // A bias common to every anchor also reads as a slope against the distance: a common
      // bias, one parameter like the scale, is tried instead (from the solution without either,
      // at its wide std). It wins when it explains a quarter of the variance too and its std is
      // not above the scale's by more than two standard errors of a std (sigma / sqrt(2 n)):
      // where the ranges cannot tell the two apart, the bias is the commoner error (an antenna
      // delay). It also wins over an implausible scale. Simulated room, three anchors each
      // 0.5 m long, whole run: std 0.425 m without, 0.1026 m with a scale of +9 % (2D RMSE
      // 0.259 m), 0.1029 m with the biases (0.035 m). Plaza2: 2.73 m, 0.529 m with +7 %, and
      // a common bias far behind (its anchors' offsets differ: 2.5, 3.0, 0.1, 3.0 m). The
      // scale's solution is kept aside.
      const auto with_scale = g.values();
      const graph::RangeGraphParams p_scale = p;
      const double sigma_scale = *sigma_with;
      g.restore(without);
      p = p_without;
      p.estimate_bias = true;
      p.common_bias = true;
      const double tie =
          2.0 / std::sqrt(2.0 * static_cast<double>(std::max<size_t>(g.ranges(), 1)));
      const bool biases_win = solveOnce(g, p) && estimateSigma() &&
                              scaleExplains(*sigma_without, p.range_sigma) &&
                              (!plausible || p.range_sigma <= sigma_scale * (1.0 + tie));
      if (biases_win) {
        ++stats_.events["range_bias_estimated"];
        ++stats_.events["range_bias_over_scale"];
        stands = false;
        biases_over_scale = true;
      } else {
        revert(with_scale, p_scale);
        stats_.estimated_range_sigma = p.range_sigma;
        if (auto_q) stats_.estimated_accel_psd = p.accel_psd;
      }
    }
    if (stands) {
      ++stats_.events["range_scale_estimated"];
    } else if (!biases_over_scale) {  // (the biases' solution, and its noise, stand)
      revert(without, p_without);
      if (auto_sigma) stats_.estimated_range_sigma = p.range_sigma;
      if (auto_q) stats_.estimated_accel_psd = p.accel_psd;
    }
  } else if (params_.scale == BiasMode::kAuto) {
    // The evidence is read with a bias per anchor free: a bias (on one anchor, or on all alike)
    // must not pass for a scale, and where the robot keeps about the same distance to an anchor
    // a scale is a bias, which the biases then take.
    // That trial solve is then undone (and when it fails, no scale is taken).
    const auto before = g.values();
    graph::RangeGraphParams with_biases = p;
    with_biases.estimate_bias = true;
    g.build(with_biases);
    if (g.solve().usable && scaleStandsOut(g.scaleEvidence())) {
      ++stats_.events["range_scale_estimated"];
      p.estimate_scale = true;
    }
    g.restore(before);
    g.build(p);
  } else {
    p.estimate_scale = params_.scale == BiasMode::kOn;
  }
  if (p.estimate_scale != scale_was_on && !constantVelocity()) {
    if (!solveOnce(g, p)) return;
    if ((auto_sigma || auto_q) && p.estimate_scale && !estimateSigma()) return;
  }
  if (biases_over_scale) {
    // the biases stand already
  } else if (params_.bias == BiasMode::kAuto) {
    bool biased = false;
    for (const auto& a : g.anchorResiduals())
      biased |= a.ranges >= kMinRangesForBias &&
                biasStandsOut(a.median_first_half, a.median_second_half, a.robust_sigma);
    if (biased) {
      // A bias makes the path fit every anchor better, so the anchors' residual spreads about
      // their own medians shrink or stay. An anchor whose surveyed position is wrong also shows
      // an offset over a short span, but taking it for a bias bends the path and the spreads
      // grow (MRPT demo, first 60 s at sigma 0.10: pooled 0.057 m without, 0.068 m with the
      // biases of -0.20 / -0.38 / +0.22 m, and uwb-ekf 0.710 m instead of 0.163 m): the biases
      // are then dropped (event range_bias_rejected_spread).
      const double spread_without = pooledSpread(g);
      const auto without = g.values();
      const graph::RangeGraphParams p_without = p;
      p.estimate_bias = true;
      if (!solveOnce(g, p)) return;
      if (widensSpread(g, spread_without)) {
        ++stats_.events["range_bias_rejected_spread"];
        revert(without, p_without);
      } else {
        ++stats_.events["range_bias_estimated"];
        preferCommonBias(g, p);
      }
    } else if (auto_sigma && params_.bias_trial) {
      // The path hides a bias on one anchor among few from the offsets; the std does not: the
      // biases are tried free, and stay when they explain a quarter of the range variance
      // (scaleExplains on the std without and with them). Every bias is freed, not only those
      // beyond the noise: a bias on every anchor alike within the noise is one too (simulated
      // greenhouse R3, 1 m under 1 m noise: 0.203 m with every bias free, 1.18 m with the
      // biases beyond the std only, 0.449 m with none).
      // The biases must not widen the anchors' spreads either (as above).
      const auto without = g.values();
      const graph::RangeGraphParams p_without = p;
      const double spread_without = pooledSpread(g);
      auto stands = [&](bool common) {
        p.estimate_bias = true;
        p.common_bias = common;
        if (solveOnce(g, p) && estimateSigma() &&
            scaleExplains(p_without.range_sigma, p.range_sigma) && !widensSpread(g, spread_without))
          return true;
        revert(without, p_without);
        stats_.estimated_range_sigma = p.range_sigma;
        return false;
      };
      bool explains = params_.bias_trial_common && stands(true);
      if (!explains && (!params_.bias_trial_common || params_.bias_trial_confirm)) {
        explains = stands(false);
        // Over a short span an odometry path's own error (slip, a scale, increments a second
        // apart) leaves slow range residuals that a bias per anchor takes up. A bias of the
        // ranges shows in the ranges alone too (see rangesAloneTakeBiases).
        if (explains && params_.bias_trial_confirm && !constantVelocity() &&
            !rangesAloneTakeBiases()) {
          ++stats_.events["range_bias_unconfirmed"];
          revert(without, p_without);
          stats_.estimated_range_sigma = p.range_sigma;
          explains = false;
        }
      }
      if (explains) {
        ++stats_.events["range_bias_estimated"];
        ++stats_.events["range_bias_explains_variance"];
        preferCommonBias(g, p);
      }
    }
  } else if (p.estimate_bias != (params_.bias == BiasMode::kOn)) {
    p.estimate_bias = params_.bias == BiasMode::kOn;
    if (!solveOnce(g, p)) return;
  }
  // The NLOS mixture: where the residuals hold a long tail (ranges through walls), a symmetric
  // loss reads the excess as noise about a longer distance and pulls the path away from the
  // anchors out of sight; under the mixture those ranges cost little and the short ones place
  // the path. Learnt from the residuals after the bias (the solved biases stay in the edges),
  // then re-solved and learnt again from the new residuals while it moves.
  if (auto_sigma && params_.nlos_mixture) {
    const auto without = g.values();
    bool state_applied = false;
    for (int round = 0; round < kMixtureRounds; ++round) {
      // (the biases are 0 unless estimated)
      const auto residuals = g.rangeResidualsLessBias();
      const auto fit = fitRangeMixture(residuals);
      if (!fit) break;
      const bool settled =
          p.range_mixture &&
          std::abs(fit->mixture.sigma / p.range_mixture->sigma - 1.0) < kSettled &&
          std::abs(fit->mixture.nlos_mean / p.range_mixture->nlos_mean - 1.0) < kSettled &&
          std::abs(fit->mixture.nlos_fraction - p.range_mixture->nlos_fraction) < kSettled;
      // From the second round each range's prior is its link's state, read from the
      // residuals of the solve under one fraction (and then under the state).
      std::optional<NlosStatePriors> state;
      if (round > 0 && params_.nlos_state) state = nlosStatePriors(g, fit->mixture, residuals);
      if (settled && (!state || state_applied)) break;
      p.range_mixture = fit->mixture;
      state_applied = state.has_value();
      g.setNlosPriors(state ? std::move(state->priors) : std::vector<double>{});
      stats_.estimated_nlos_memory.reset();
      if (state) stats_.estimated_nlos_memory = state->memory;
      ++stats_.events[state_applied ? "nlos_state_solves" : "range_mixture_solves"];
      if (!solveOnce(g, p)) {
        p.range_mixture.reset();
        g.setNlosPriors({});
        stats_.estimated_nlos_memory.reset();
        g.restore(without);
        if (!solveOnce(g, p)) return;
        break;
      }
    }
  }
  // The odometry model's factor, last: read with the range model settled. The range std stays
  // the one found above (learnt again at the new factor, it lost the part of the error the
  // biases take only on average, as above: the simulated room with every range 0.5 m long,
  // 0.021 m instead of 0.015 m).
  if (!constantVelocity() && !front_ && params_.odom_noise.isAuto()) {
    const double factor = crossValidatedOdometryFactor(g, p);
    stats_.estimated_motion_scale = factor;
    if (factor != p.odometry_sigma_factor) {
      p.odometry_sigma_factor = factor;
      if (!solveOnce(g, p)) return;
    }
  }
  for (const auto& a : g.anchorResiduals())
    if (a.ranges > 0)
      stats_.estimated_noise[a.anchor_id] = {p.estimate_bias ? a.bias : a.median, a.robust_sigma,
                                             a.ranges};
  if (p.estimate_scale) stats_.estimated_range_scale = g.scale();
  // Several tags: each one's spread, as tags on one robot may range unlike each other (a tag
  // behind the robot's body, another make).
  if (const auto tags = g.tagSigmas(); tags.size() >= 2)
    for (const auto& [tag, s] : tags) stats_.estimated_tag_noise[tag] = {0.0, s.second, s.first};
  if (auto_sigma) {
    const auto residuals = g.rangeResiduals();
    if (auto fit = fitRangeMixture(residuals)) {
      stats_.estimated_range_mixture = fit->mixture;
      stats_.estimated_range_mixture->weight = independentShare(residuals);
      ++stats_.events["range_mixture_learnt"];
    }
  }
}

std::optional<NlosStatePriors> GraphSmoother::nlosStatePriors(
    const graph::RangeGraph& g, const RangeMixture& m,
    const std::vector<std::pair<int, double>>& residuals) const {
  const auto edges = g.rangeEdges();
  if (edges.size() != range_times_.size()) return std::nullopt;  // ranges not from addRanges
  std::vector<NlosSample> samples(edges.size());
  for (size_t k = 0; k < edges.size(); ++k)
    samples[k] = {edges[k].anchor_id, edges[k].tag_id, range_times_[k], residuals[k].second,
                  m.sigma * std::sqrt(edges[k].variance_scale)};
  return loc::nlosStatePriors(m, samples);
}

// The MRPT demo without its manifest's sigma, first 60 s (the particle filters' learning start):
// with the odometry the biases of +0.01 / -0.16 / +0.07 m explain the variance (std 0.107 ->
// 0.070 m) and agree between the two halves, yet the reference gives -0.07 / -0.05 / -0.02 m over
// the run and uwb-pf goes 0.139 -> 0.269 m with them; graph-uwb on the same ranges does not take
// them (0.127 -> 0.117 m). A 0.5 m bias on one of three simulated anchors both take.
bool GraphSmoother::rangesAloneTakeBiases() const {
  GraphSmootherParams cv;  // graph-uwb's defaults
  cv.front = params_.front;
  cv.motion = GraphMotion::kConstantVelocity;
  cv.nlos_mixture = false;  // decided after the biases: only their answer is read here
  GraphSmoother alone(cv, context_);
  const int primary = primaryTag(context_);
  for (const auto& r : ranges_)
    if (r.measurement.tag_id == primary) alone.ranges_.push_back(r);
  alone.first_t_ = first_t_;
  alone.started_ = started_;
  alone.doFinishAll();
  return alone.stats_.events.count("range_bias_estimated") > 0;
}

std::vector<PoseEstimate> GraphSmoother::doFinishAll() {
  if (online()) return finishWindow();
  if (front_) {
    for (auto& e : front_->finishAll()) front_estimates_.push_back(e);
    mergeFrontStatistics();
  }
  graph::RangeGraph g;
  g.setAnchors(context_.anchors);
  const std::vector<double> times = addPoseVertices(g);
  if (times.empty()) return {};
  if (icp_ && front_) addIcpEdges(g, times);
  if (front_ && !corners_.empty()) addLandmarks(g, times);
  addRanges(g, times);
  solveBatch(g);
  if (constantVelocity()) {
    // The smoothed path's mean squared speed over its span (what a filter's velocity decay is
    // matched to: see UwbEkf::learn).
    double speed_sq = 0.0, span = 0.0;
    for (size_t i = 1; i < g.poses(); ++i) {
      const double dt = times[i] - times[i - 1];
      speed_sq += (g.pose(i) - g.pose(i - 1)).head<2>().squaredNorm() / dt;
      span += dt;
    }
    if (span > 0.0) stats_.mean_square_speed = speed_sq / span;
    return trackPoses(g, times);
  }
  std::vector<PoseEstimate> out;
  out.reserve(g.poses());
  const auto covariances =
      params_.covariance ? g.poseCovariances() : std::vector<Eigen::Matrix3d>{};
  for (size_t i = 0; i < g.poses(); ++i) {
    PoseEstimate e;
    e.t = times[i];
    e.pose = g.pose(i);
    if (!covariances.empty()) e.covariance = covariances[i];
    out.push_back(e);
  }
  return out;
}

}  // namespace uwbloc::loc
