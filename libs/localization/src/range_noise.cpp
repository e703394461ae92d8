#include "uwbloc/localization/range_noise.hpp"

#include <algorithm>
#include <sstream>

#include "uwbloc/localization/graph/range_graph.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::loc {

bool scaleStandsOut(const graph::ScaleEvidence& e) {
  if (e.ranges[0] < 20 || !(std::abs(e.slope[0]) > 3.0 * e.slope_std[0])) return false;
  if (!(e.explained[0] >= 0.25)) return false;
  return std::abs(e.slope[1] - e.slope[2]) < 3.0 * std::hypot(e.slope_std[1], e.slope_std[2]);
}

void RangeNoiseModel::learn(const std::map<int, NoiseEstimate>& noise, bool use_bias,
                            std::optional<double> sigma, std::optional<double> scale) {
  learnt_noise_ = noise;
  if (!use_bias)
    for (auto& [id, n] : learnt_noise_) n.bias = 0.0;
  if (sigma && std::isfinite(*sigma) && *sigma > 0.0) learnt_sigma_ = sigma;
  if (scale && std::isfinite(*scale) && *scale > -0.5) learnt_scale_ = scale;
}

std::unique_ptr<Estimator> makeRangeLearner(const AutoDouble& sigma, const AutoDouble* q,
                                            const RangeLearningParams& learning,
                                            const EstimatorContext& context) {
  const bool q_auto = q && q->isAuto();
  if (!(learning.calib > 0.0) ||
      !(sigma.isAuto() || q_auto || learning.calib_bias != BiasMode::kOff))
    return nullptr;
  // The ranges alone, as the method sees them: graph-uwb over the first seconds.
  std::ostringstream spec;
  spec << "graph-uwb:sigma=" << sigma << ",bias=" << enumName(learning.calib_bias);
  if (q) spec << ",q=" << *q;
  return Registry::builtin().create(spec.str(), context);
}

void learnAccelPsd(const EstimatorStatistics& learnt, const AutoDouble& q, double tau,
                   double& accel_psd, EstimatorStatistics& stats) {
  if (!q.isAuto() || !learnt.estimated_accel_psd) return;
  double learnt_q = *learnt.estimated_accel_psd;
  if (tau > 0.0 && learnt.mean_square_speed)
    learnt_q = std::max(learnt_q, *learnt.mean_square_speed / tau);
  if (learnt_q > accel_psd) {
    accel_psd = learnt_q;
    ++stats.events["q_raised"];
  }
  stats.estimated_accel_psd = accel_psd;
}

void RangeNoiseModel::learnFrom(const EstimatorStatistics& learnt, BiasMode calib_bias,
                                bool sigma_auto) {
  const bool biased =
      calib_bias == BiasMode::kOn || learnt.events.count("range_bias_estimated") != 0;
  learn(learnt.estimated_noise, biased, sigma_auto ? learnt.estimated_range_sigma : std::nullopt,
        learnt.estimated_range_scale);
}

double RangeNoiseModel::widened(double sigma_now, EstimatorStatistics& stats) const {
  if (!learnt_sigma_) return sigma_now;
  if (sigma() > sigma_now) return sigma();
  ++stats.events["sigma_kept_at_start"];
  return sigma_now;
}

void RangeNoiseModel::report(EstimatorStatistics& stats) const {
  if (!learnt_noise_.empty()) stats.estimated_noise = learnt_noise_;
  if (learnt_sigma_) stats.estimated_range_sigma = learnt_sigma_;
  if (learnt_scale_) stats.estimated_range_scale = learnt_scale_;
}

std::optional<PoseEstimate> LearningStart::process(const Event& event, const Learnt& learnt,
                                                   const Step& step) {
  if (learner_) {
    const double t = eventTime(event);
    if (!t0_) t0_ = t;
    kept_.push_back(event);
    learner_->process(event);
    if (t - *t0_ >= span_) end(learnt, step);
  } else if (auto out = step(event)) {
    pending_.push_back(*out);
  }
  if (pending_.empty()) return std::nullopt;
  PoseEstimate out = pending_.front();
  pending_.pop_front();
  return out;
}

std::vector<PoseEstimate> LearningStart::finish(const Learnt& learnt, const Step& step) {
  if (learner_) end(learnt, step);
  std::vector<PoseEstimate> out(pending_.begin(), pending_.end());
  pending_.clear();
  return out;
}

void LearningStart::end(const Learnt& learnt, const Step& step) {
  learner_->finishAll();
  learnt(learner_->statistics());
  learner_.reset();
  for (const auto& e : kept_)
    if (auto out = step(e)) pending_.push_back(*out);
  kept_.clear();
  kept_.shrink_to_fit();
}

}  // namespace uwbloc::loc
