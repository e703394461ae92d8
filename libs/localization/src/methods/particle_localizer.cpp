#include "uwbloc/localization/methods/particle_localizer.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include "uwbloc/localization/lidar/occupancy_map.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::loc {

namespace {
MotionNoise scaledMotion(const MotionNoise& m, double scale) {
  MotionNoise out = m;
  out.alpha1 *= scale, out.alpha2 *= scale, out.alpha3 *= scale, out.alpha4 *= scale;
  return out;
}

ParticleFilterParams filterParams(const ParticleCoreParams& p) {
  ParticleFilterParams f;
  f.particles = p.particles;
  f.ess_threshold = p.ess;
  f.motion = scaledMotion(p.motion, p.motion_scale.value.value_or(1.0));
  f.initial_particles = p.init_n;
  f.max_particles = p.max_particles;
  f.kld_epsilon = p.kld_epsilon;
  f.kld_bin_xy = p.kld_bin_xy;
  f.kld_bin_theta = p.kld_bin_theta_deg * M_PI / 180.0;
  return f;
}

// a_scale=auto's candidates, the default's 1 among them; the likelihood ratio over the
// default's that another must pass (20: ln 20 = 3.0) to be taken, and how many of the trials'
// own Monte Carlo standard deviations.
constexpr std::array<double, 6> kMotionScales{2.0, 1.0, 0.5, 0.25, 0.125, 0.0625};
constexpr double kMotionScaleMargin = 2.995732273553991;
constexpr double kMotionScaleSpreads = 3.0;

// The learner of a Calibration with a mixture learner: the learner takes the events of its
// span, the mixture learner those of its own (the LearningStart lasts the longer); the
// statistics are the learner's, with the mixture learner's range mixture (or its absence) in
// place of its own.
class JointLearner final : public Estimator {
 public:
  JointLearner(std::unique_ptr<Estimator> learner, double span,
               std::unique_ptr<Estimator> mixture_learner)
      : learner_(std::move(learner)), mixture_learner_(std::move(mixture_learner)), span_(span) {}

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override {
    const double t = eventTime(event);
    if (!t0_) t0_ = t;
    mixture_learner_->process(event);
    // As a LearningStart of the learner's own span would: up to and with the first event at or
    // past its end.
    if (!learner_done_) learner_->process(event);
    learner_done_ = learner_done_ || t - *t0_ >= span_;
    return std::nullopt;
  }
  std::vector<PoseEstimate> doFinishAll() override {
    mixture_learner_->finishAll();
    auto out = learner_->finishAll();
    stats_ = learner_->statistics();
    const EstimatorStatistics& m = mixture_learner_->statistics();
    stats_.estimated_range_mixture = m.estimated_range_mixture;
    if (m.events.count("range_model_at_filter_pose"))
      ++stats_.events["range_mixture_at_lidar_pose"];
    return out;
  }

 private:
  std::unique_ptr<Estimator> learner_, mixture_learner_;
  double span_;
  std::optional<double> t0_;
  bool learner_done_ = false;
};

std::unique_ptr<Estimator> makeLearner(const Calibration& c, const EstimatorContext& context) {
  auto learner = Registry::builtin().create(c.learner, context);
  if (c.mixture_learner.empty()) return learner;
  return std::make_unique<JointLearner>(std::move(learner), c.span,
                                        Registry::builtin().create(c.mixture_learner, context));
}
}  // namespace

namespace detail {
std::unique_ptr<ParticleLocalizer> buildParticleLocalizer(const ParticleCoreParams& core,
                                                          const EstimatorContext& context,
                                                          const LidarPartParams* lidar,
                                                          const UwbPartParams* uwb,
                                                          const SwarmPartParams* swarm) {
  std::vector<std::unique_ptr<EpochMeasurement>> measurements;
  if (lidar) {
    if (!context.map)
      throw ParamError("this method needs a map: give the manifest's [dataset] map");
    measurements.push_back(std::make_unique<LidarFieldMeasurement>(*lidar, context.map));
    if (lidar->range_model) measurements.push_back(std::make_unique<RangeModelProbe>(context));
  }
  if (uwb)
    measurements.push_back(std::make_unique<UwbRangeMeasurement>(*uwb, context, lidar != nullptr));
  std::unique_ptr<PosteriorStep> posterior;
  if (swarm)
    posterior = std::make_unique<SwarmStep>(*swarm);
  else
    posterior = std::make_unique<ResamplingStep>();
  auto pf = std::make_unique<ParticleLocalizer>(core, context, std::move(measurements),
                                                std::move(posterior));
  if (lidar) pf->setRelocaliseParticles(lidar->relocalise_n);
  if (core.motion_scale.isAuto()) {
    // The trials' parts are copies, kept with the factory: the caller's may be gone by then.
    std::optional<LidarPartParams> l;
    std::optional<UwbPartParams> u;
    std::optional<SwarmPartParams> s;
    if (lidar) l = *lidar;
    // The trial takes the model learnt already, and weighs every range: a range the NLOS test
    // rejects adds nothing to the evidence, and a filter lost under too small a noise rejects
    // the most (simulated, odometry 10 times worse than the defaults assume: -115 at 1/16
    // against -136 at 1, where the filter ended 7.3 m off against 0.49 m).
    if (uwb) u = *uwb, u->calib = 0.0, u->nlos_action = NlosAction::kDownweight;
    if (swarm) s = *swarm;
    pf->setTrialFactory([core, context, l, u, s](double scale, uint64_t seed) {
      ParticleCoreParams c = core;
      c.motion_scale.value = scale;
      EstimatorContext trial_context = context;
      trial_context.seed = seed;
      return buildParticleLocalizer(c, trial_context, l ? &*l : nullptr, u ? &*u : nullptr,
                                    s ? &*s : nullptr);
    });
  }
  return pf;
}
}  // namespace detail

ParticleLocalizer::ParticleLocalizer(const ParticleCoreParams& core,
                                     const EstimatorContext& context,
                                     std::vector<std::unique_ptr<EpochMeasurement>> measurements,
                                     std::unique_ptr<PosteriorStep> posterior)
    : core_(core),
      context_(context),
      pf_(filterParams(core), makeResampler(core.resampler), context.seed),
      measurements_(std::move(measurements)),
      posterior_(std::move(posterior)),
      fitness_([this](double x, double y, double th) { return epochLogLikelihood(x, y, th); }) {
  if (core_.particles < 1) throw ParamError("parameter 'n' must be at least 1");
  if (core_.init_n < 0) throw ParamError("parameter 'init_n' must be 0 or more");
  if (core_.init == InitMode::kGlobal && !context.map)
    throw ParamError("init=global needs a map: give the manifest's [dataset] map");
  if (core_.init == InitMode::kTracking && !context.initial_pose)
    throw ParamError("tracking initialisation needs a start pose (the dataset's ground truth)");
  // The learning method smooths from the start pose; without one the model stays as given.
  for (const auto& m : measurements_)
    if (const auto c = m->calibration(); c && context.initial_pose)
      start_ = LearningStart(makeLearner(*c, context), std::max(c->span, c->mixture_span));
  if (core_.motion_scale.isAuto() && !start_.learning())
    ++stats_.events["motion_scale_not_learnt"];  // nothing to judge the scales by: a1-a4 as set
}

std::vector<std::pair<std::string, std::string>> ParticleLocalizer::artifacts() const {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& m : measurements_) m->addArtifacts(out);
  posterior_->addArtifacts(out);
  return out;
}

namespace {
// SE(2)'s logarithm and exponential: the constant twist (per unit time) that makes an increment
// over `span`, and the increment that a twist makes over a time.
Eigen::Vector3d twistOf(const Eigen::Vector3d& delta, double span) {
  const double th = delta.z();
  Eigen::Vector2d v = delta.head<2>();
  if (std::abs(th) > 1e-9) {
    const double a = std::sin(th) / th, b = (1.0 - std::cos(th)) / th;
    v = Eigen::Vector2d(a * delta.x() + b * delta.y(), -b * delta.x() + a * delta.y()) /
        (a * a + b * b);
  }
  return Eigen::Vector3d(v.x(), v.y(), th) / span;
}
Eigen::Vector3d incrementOf(const Eigen::Vector3d& twist, double dt) {
  const Eigen::Vector3d u = twist * dt;
  const double th = u.z();
  if (std::abs(th) <= 1e-9) return u;
  const double a = std::sin(th) / th, b = (1.0 - std::cos(th)) / th;
  return {a * u.x() - b * u.y(), b * u.x() + a * u.y(), th};
}
}  // namespace

// Between odometry increments the particles stand where the last one left them; a range or a
// scan taken later is weighed there unless they are carried to its time. The carried motion is
// the last increment's twist, at most one increment's span ahead, without noise; the next
// increment undoes it and moves them with its own noise, so that at each increment the cloud
// is what it would have been without the carry.
void ParticleLocalizer::carryTo(double t) {
  if (!core_.carry || !(odo_span_ > 0.0) || !(t > cloud_t_)) return;
  const double ahead = std::min(t, odo_t_ + odo_span_) - odo_t_;
  if (!(ahead > 0.0)) return;
  const Eigen::Vector3d target = incrementOf(odo_twist_, ahead);
  pf_.shift(relativePose(carried_, target));
  carried_ = target;
  cloud_t_ = odo_t_ + ahead;
}

void ParticleLocalizer::odometry(const OdometryIncrement& odo) {
  if (!carried_.isZero()) pf_.shift(relativePose(carried_, Eigen::Vector3d::Zero()));
  carried_.setZero();
  pf_.predict(odo.delta);
  const double span = odo.t - odo_t_;
  if (span > 1e-6) {  // the first increment, or one at the previous one's time, sets no rate
    odo_span_ = span;
    odo_twist_ = twistOf(odo.delta, span);
  }
  odo_t_ = odo.t;
  cloud_t_ = odo.t;
}

void ParticleLocalizer::initialise() {
  carried_.setZero();
  odo_t_ = cloud_t_ = NAN;
  odo_span_ = 0.0;
  for (auto& m : measurements_) m->reset();
  pf_.setStartParticles(core_.init_n);
  if (core_.init == InitMode::kTracking) {
    pf_.initUniformBox(*context_.initial_pose,
                       {core_.init_xy, core_.init_xy, core_.init_theta_deg * M_PI / 180.0});
  } else {
    pf_.initUniform(context_.map->freeCells(), context_.map->resolution());
  }
}

double ParticleLocalizer::epochLogLikelihood(double x, double y, double theta) const {
  double l = 0.0;
  for (const auto& m : measurements_) l = m->addLogLikelihood(l, x, y, theta);
  return l;
}

std::optional<PoseEstimate> ParticleLocalizer::finishEpoch() {
  epoch_open_ = false;
  posterior_->beginEpoch(pf_);
  for (auto& m : measurements_) m->weight(pf_, stats_);
  bool scan = false;
  for (const auto& m : measurements_) scan = scan || m->hasScan();
  posterior_->epochKind(scan);
  posterior_->apply(pf_, fitness_, epoch_t_, stats_);
  const ParticleEstimate e = pf_.estimate();
  PoseEstimate est;
  est.t = epoch_t_;
  est.pose = e.mean;
  est.covariance = e.covariance;
  for (auto& m : measurements_) m->endEpoch(est);
  for (const auto& m : measurements_)
    if (m->lost()) {
      relocalise();
      break;
    }
  return est;
}

// Lost (a measurement model says so, e.g. the scans no longer fit the map at the estimate):
// particles over the whole map's free space, many of them, down to n once they converge.
void ParticleLocalizer::relocalise() {
  ++stats_.events["relocalised"];
  ++stats_.resets;
  for (auto& m : measurements_) m->reset();
  if (!context_.map) return;
  pf_.setStartParticles(std::max(relocalise_n_, core_.particles));
  pf_.initUniform(context_.map->freeCells(), context_.map->resolution());
}

void ParticleLocalizer::learnt(const EstimatorStatistics& learnt) {
  for (auto& m : measurements_) m->calibrate(learnt, stats_);
  ++stats_.events["range_model_learnt"];
  if (core_.motion_scale.isAuto()) learnMotionScale(learnt);
}

// The odometry noise a1-a4 describes the recording as the range noise does, and the defaults
// (MRPT's kind of robot) are far off for some: on CMU Plaza2, whose wheel odometry holds its
// heading to a few degrees over tens of metres, uwb-pf let its heading wander 18.6 deg RMS and
// scored 0.691 m; with a1-a4 at 1/20 of the defaults, 0.404 m. The filter itself says which
// noise fits: the particles' mean likelihood of each epoch's ranges, multiplied over the
// epochs, is the ranges' marginal likelihood under that motion model. Over the whole of Plaza2
// it rises from -1681 (scale 1) to -1176 (1/20) as the RMSE falls; on the MRPT demo it peaks at
// the defaults (-326 against -361 at 1/2 and -346 at 2), where the RMSE is lowest too. The
// trials run over the learning start's events only, with the model it learnt.
void ParticleLocalizer::learnMotionScale(const EstimatorStatistics& learnt) {
  if (!make_trial_) return;
  // Two trials per scale, from the run's seed and the next: the mean is the scale's evidence,
  // and the pairs' differences give the estimates' Monte Carlo spread, pooled over the scales
  // tried. Where the ranges alone fix the position (simulated rooms, 0.1 m at 10 Hz), one
  // trial's evidence moved by 5-75 between seeds while the RMSE hardly depended on the scale;
  // a scale is taken only when it stands out of that spread. The scales are tried from 1 and
  // its two neighbours on, further down while the evidence still rises (the evidence of the
  // scales is one-peaked where it stands out of the noise).
  std::map<double, double> evidence;
  double spread2 = 0.0;
  auto tryScale = [&](double scale) {
    const auto& events = start_.kept();
    const double l1 = make_trial_(scale, context_.seed)->logEvidenceOver(learnt, events);
    const double l2 = make_trial_(scale, context_.seed + 1)->logEvidenceOver(learnt, events);
    spread2 += 0.5 * (l1 - l2) * (l1 - l2);
    return evidence[scale] = 0.5 * (l1 + l2);
  };
  tryScale(kMotionScales[0]);
  double last = tryScale(kMotionScales[1]);
  for (size_t k = 2; k < kMotionScales.size(); ++k) {
    const double l = tryScale(kMotionScales[k]);
    if (!(l > last)) break;
    last = l;
  }
  const auto best =
      std::max_element(evidence.begin(), evidence.end(),
                       [](const auto& a, const auto& b) { return a.second < b.second; });
  // Two means of two trials each: their difference has the spread of one trial.
  const double spread = std::sqrt(spread2 / static_cast<double>(evidence.size()));
  const double margin = std::max(kMotionScaleMargin, kMotionScaleSpreads * spread);
  const double scale = best->second > evidence[1.0] + margin ? best->first : 1.0;
  pf_.setMotion(scaledMotion(core_.motion, scale));
  stats_.estimated_motion_scale = scale;
  ++stats_.events[scale == 1.0 ? "motion_scale_kept" : "motion_scale_learnt"];
}

double ParticleLocalizer::logEvidenceOver(const EstimatorStatistics& learnt,
                                          const std::vector<Event>& events) {
  for (auto& m : measurements_) m->calibrate(learnt, stats_);
  for (const auto& e : events) step(e);
  if (epoch_open_) finishEpoch();
  return pf_.logEvidence();
}

std::vector<PoseEstimate> ParticleLocalizer::doFinishAll() {
  std::vector<PoseEstimate> out = start_.finish(learnt_, step_);
  if (epoch_open_) out.push_back(*finishEpoch());
  for (auto& m : measurements_) m->finish(stats_);
  if (pf_.resamplesAboveLeast() > 0) {
    stats_.events["kld_resamplings_above_n"] = pf_.resamplesAboveLeast();
    stats_.events["kld_most_particles"] = static_cast<long>(pf_.mostDrawn());
  }
  return out;
}

std::optional<PoseEstimate> ParticleLocalizer::doFinish() { return newestOfFinishAll(); }

std::optional<PoseEstimate> ParticleLocalizer::doProcess(const Event& event) {
  return start_.process(event, learnt_, step_);
}

std::optional<PoseEstimate> ParticleLocalizer::step(const Event& event) {
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
    // From the start pose at its time: the motion recorded before it is already in that pose.
    if (core_.init == InitMode::kTracking && odo->t <= context_.startTime()) {
      countRejection("odometry_before_start");
      return out;
    }
    if (epoch_open_) out = finishEpoch();  // motion at the epoch's own time: close it first
    odometry(*odo);
    return out;
  }
  bool taken = false;
  for (auto& m : measurements_) taken = taken || m->take(event, stats_);
  if (taken && !epoch_open_) {
    carryTo(t);  // an event no part takes (a range to a filter without UWB) moves nothing
    epoch_open_ = true;
    epoch_t_ = t;
  }
  return out;
}

}  // namespace uwbloc::loc
