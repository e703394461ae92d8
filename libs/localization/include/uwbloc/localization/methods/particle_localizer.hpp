// Particle-filter localisers composed of parts (pf/parts.hpp): the odometry motion model, the
// measurement models a registry entry chooses (LiDAR likelihood field, UWB ranges with the NLOS
// test) and a posterior step (resampling, or the PF-IBAS beetle swarm).
//
// Measurements are processed per epoch (everything with one timestamp: a scan and its ranges).
// At the epoch's close the measurement models weight the particles in order (the LiDAR first, so
// that the UWB NLOS test judges ranges against the pose after the LiDAR update), then the
// posterior step resamples or moves the particles, and the estimate is the weighted mean.
//
// A measurement model that learns from a batch (the UWB ranges with sigma=auto or a bias) makes
// the filter start with a calibration: the events of the first `calib` seconds are kept and
// given to the learning method (the range + odometry graph) as well; when the span is over (or
// the stream ends) its model is taken and the kept events are filtered. Their estimates are
// queued and handed out one per later event (or at the end), so a caller still gets at most one
// per event, each with its own time, with a lag that the events without an estimate drain.
#pragma once

#include <deque>
#include <functional>
#include <memory>
#include <tuple>
#include <type_traits>
#include <vector>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/pf/parts.hpp"
#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc {

class ParticleLocalizer : public Estimator {
 public:
  /// `measurements` in the order they weight an epoch.
  ParticleLocalizer(const ParticleCoreParams& core, const EstimatorContext& context,
                    std::vector<std::unique_ptr<EpochMeasurement>> measurements,
                    std::unique_ptr<PosteriorStep> posterior);
  ParticleLocalizer(const ParticleLocalizer&) = delete;  // start_'s callbacks hold `this`
  ParticleLocalizer& operator=(const ParticleLocalizer&) = delete;

  std::vector<std::pair<std::string, std::string>> artifacts() const override;
  const ParticleFilter& filter() const { return pf_; }
  /// Particles spread over the map when a measurement model judges the filter lost.
  void setRelocaliseParticles(int n) { relocalise_n_ = n; }
  /// A fresh filter of this one's make-up whose a1-a4 are scaled by `motion_scale`, drawing
  /// from `seed`, without a learning start (a_scale=auto's trials); set by the builder.
  using TrialFactory =
      std::function<std::unique_ptr<ParticleLocalizer>(double motion_scale, uint64_t seed)>;
  void setTrialFactory(TrialFactory make) { make_trial_ = std::move(make); }

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::vector<PoseEstimate> doFinishAll() override;
  /// The end of the stream for a caller that takes one estimate: the newest (finishAll() gives
  /// every queued one).
  std::optional<PoseEstimate> doFinish() override;
  void reset() override { initialise(); }

 private:
  void initialise();
  /// One event through the filter.
  std::optional<PoseEstimate> step(const Event& event);
  /// The calibration's learnt model to the parts.
  void learnt(const EstimatorStatistics& learnt);
  /// a_scale=auto: the odometry noise's scale under which the learning start's measurements are
  /// likeliest, each candidate filtered from the start by a trial filter.
  void learnMotionScale(const EstimatorStatistics& learnt);
  /// On a fresh trial filter: takes the `learnt` range model, filters `events` and returns the
  /// log of their measurements' marginal likelihood (ParticleFilter::logEvidence).
  double logEvidenceOver(const EstimatorStatistics& learnt, const std::vector<Event>& events);
  /// A measurement model judged the filter lost: spread particles over the map again.
  void relocalise();
  std::optional<PoseEstimate> finishEpoch();
  /// Carries the particles to time t at the last odometry increment's rate (core_.carry).
  void carryTo(double t);
  /// An odometry increment: the carried motion undone, then the increment with its noise.
  void odometry(const OdometryIncrement& odo);
  /// The epoch's log-likelihood at one pose, summed over the measurement models.
  double epochLogLikelihood(double x, double y, double theta) const;

  ParticleCoreParams core_;
  EstimatorContext context_;
  ParticleFilter pf_;
  std::vector<std::unique_ptr<EpochMeasurement>> measurements_;
  std::unique_ptr<PosteriorStep> posterior_;
  EpochFitness fitness_;  ///< epochLogLikelihood, bound once
  double epoch_t_ = 0.0;
  bool epoch_open_ = false;
  int relocalise_n_ = 0;  ///< particles for relocalising (the LiDAR part's relocalise_n)
  TrialFactory make_trial_;
  // Motion between odometry increments (carryTo): the last increment's time, its span and its
  // twist per second, the time the particles stand at, and the motion carried since it.
  double odo_t_ = NAN, odo_span_ = 0.0, cloud_t_ = NAN;
  Eigen::Vector3d odo_twist_ = Eigen::Vector3d::Zero(), carried_ = Eigen::Vector3d::Zero();
  // Calibration (see above), with step() and learnt() bound once.
  LearningStart start_;
  LearningStart::Learnt learnt_ = [this](const EstimatorStatistics& s) { learnt(s); };
  LearningStart::Step step_ = [this](const Event& e) { return step(e); };
};

/// The parameters of a particle-filter method: the filter's own, then one struct per part.
/// A registry entry names the parts (e.g. PfMethodParams<LidarPartParams, UwbPartParams,
/// SwarmPartParams> for PF-IBAS); `uwbloc methods` lists exactly their keys.
template <class... Parts>
struct PfMethodParams {
  ParticleCoreParams core;
  std::tuple<Parts...> parts;

  template <class P>
  static constexpr bool has = (std::is_same_v<P, Parts> || ...);
  template <class P>
  const P& part() const {
    return std::get<P>(parts);
  }
  template <class V>
  void visit(V&& v) {
    core.visit(v);
    std::apply([&](auto&... p) { (p.visit(v), ...); }, parts);
  }
};

namespace detail {
std::unique_ptr<ParticleLocalizer> buildParticleLocalizer(const ParticleCoreParams& core,
                                                          const EstimatorContext& context,
                                                          const LidarPartParams* lidar,
                                                          const UwbPartParams* uwb,
                                                          const SwarmPartParams* swarm);
}  // namespace detail

/// Builds the localiser from the parts its parameters name.
template <class... Parts>
std::unique_ptr<Estimator> makeParticleLocalizer(const PfMethodParams<Parts...>& p,
                                                 const EstimatorContext& context) {
  using P = PfMethodParams<Parts...>;
  const LidarPartParams* lidar = nullptr;
  const UwbPartParams* uwb = nullptr;
  const SwarmPartParams* swarm = nullptr;
  if constexpr (P::template has<LidarPartParams>) lidar = &p.template part<LidarPartParams>();
  if constexpr (P::template has<UwbPartParams>) uwb = &p.template part<UwbPartParams>();
  if constexpr (P::template has<SwarmPartParams>) swarm = &p.template part<SwarmPartParams>();
  return detail::buildParticleLocalizer(p.core, context, lidar, uwb, swarm);
}

}  // namespace uwbloc::loc
