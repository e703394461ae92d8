#include "uwbloc/localization/range_noise.hpp"

#include <algorithm>
#include <cstdint>
#include <deque>
#include <future>
#include <mutex>
#include <sstream>
#include <type_traits>

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

namespace {

// FNV-1a over the bytes of plain values: the identity of a learning start's inputs.
class Fingerprint {
 public:
  template <typename T>
  void add(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const unsigned char*>(&v);
    for (size_t i = 0; i < sizeof(T); ++i) h_ = (h_ ^ p[i]) * 1099511628211ull;
  }
  template <typename T>
  void add(const std::optional<T>& v) {
    add(v.has_value());
    if (v) add(*v);
  }
  template <typename T>
  void add(const std::vector<T>& v) {
    add(v.size());
    for (const auto& x : v) add(x);
  }
  void add(const Eigen::Vector2d& v) { add(v.x()), add(v.y()); }
  void add(const Eigen::Vector3d& v) { add(v.x()), add(v.y()), add(v.z()); }
  void add(const uwb::Range& r) {
    add(r.t), add(r.anchor_id), add(r.tag_id), add(r.on_robot), add(r.range);
    add(r.tag_on_robot), add(r.rx_power_dbm), add(r.fp_power_dbm), add(r.nlos_probability);
  }
  void add(const OdometryIncrement& o) { add(o.t), add(o.delta); }
  void add(const LaserScan& s) {
    add(s.t), add(s.sensor_pose), add(s.sensor_height), add(s.angle_min);
    add(s.angle_increment), add(s.max_range), add(s.ranges), add(s.valid);
  }
  void add(const ImuSample& m) { add(m.t), add(m.accel), add(m.gyro_z); }
  void add(const Event& e) {
    add(e.index());
    std::visit([this](const auto& v) { add(v); }, e);
  }
  std::string hex() const {
    std::ostringstream out;
    out << std::hex << h_;
    return out.str();
  }

 private:
  uint64_t h_ = 14695981039346656037ull;
};

}  // namespace

EstimatorStatistics LearningCache::get(const std::string& key,
                                       const std::function<EstimatorStatistics()>& solve,
                                       bool* reused) {
  // The first run with this key solves it; the others (at once, or later) wait for its result.
  std::shared_future<EstimatorStatistics> earlier;
  std::promise<EstimatorStatistics> solving;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [k, s] : models_)
      if (k == key) earlier = s;
    if (!earlier.valid()) {
      models_.emplace_back(key, solving.get_future().share());
      if (models_.size() > kept_) models_.pop_front();
    }
  }
  *reused = earlier.valid();
  if (earlier.valid()) return earlier.get();
  try {
    EstimatorStatistics s = solve();
    solving.set_value(s);
    return s;
  } catch (...) {
    solving.set_exception(std::current_exception());
    std::lock_guard lock(mutex_);
    models_.erase(std::remove_if(models_.begin(), models_.end(),
                                 [&](const auto& km) { return km.first == key; }),
                  models_.end());
    throw;
  }
}

void countLearnt(const EstimatorStatistics& learnt, EstimatorStatistics& stats) {
  ++stats.events["range_model_learnt"];
  if (learnt.events.count("range_model_reused")) ++stats.events["range_model_reused"];
}

LearningStart makeLearningStart(const AutoDouble& sigma, const AutoDouble* q,
                                const RangeLearningParams& learning,
                                const EstimatorContext& context) {
  const bool q_auto = q && q->isAuto();
  if (!(learning.calib > 0.0) ||
      !(sigma.isAuto() || q_auto || learning.calib_bias != BiasMode::kOff))
    return {};
  // The ranges alone, as the method sees them: graph-uwb over the first seconds.
  std::ostringstream spec;
  spec << "graph-uwb:sigma=" << sigma << ",bias=" << enumName(learning.calib_bias);
  if (q) spec << ",q=" << *q;
  // The ranges' own model as before the graph took the NLOS mixture (the filters learn the
  // mixture from the residuals themselves).
  spec << ",nlos_mixture=0";
  // Everything of the context that graph-uwb reads (not the map, nor the NLOS models: a spec
  // without nlos_model never asks for one).
  Fingerprint f;
  for (const auto& a : context.anchors) f.add(a.id), f.add(a.position);
  f.add(context.initial_pose), f.add(context.initial_time), f.add(context.seed);
  f.add(context.range_sigma), f.add(context.robot_tags), f.add(learning.calib);
  return LearningStart(Registry::builtin().create(spec.str(), context), learning.calib,
                       spec.str() + "|" + f.hex(), context.learning_cache);
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
    if (!shared()) learner_->process(event);
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

EstimatorStatistics LearningStart::solve() {
  // A shared start's learner has not seen the kept events yet.
  if (shared())
    for (const auto& e : kept_) learner_->process(e);
  learner_->finishAll();
  return learner_->statistics();
}

EstimatorStatistics LearningStart::sharedStatistics() {
  Fingerprint f;
  for (const auto& e : kept_) f.add(e);
  const std::string key = share_key_ + "|" + std::to_string(kept_.size()) + "|" + f.hex();
  bool reused = false;
  EstimatorStatistics s = cache_->get(
      key, [this] { return solve(); }, &reused);
  if (reused) ++s.events["range_model_reused"];
  return s;
}

void LearningStart::end(const Learnt& learnt, const Step& step) {
  learnt(shared() ? sharedStatistics() : solve());
  learner_.reset();
  for (const auto& e : kept_)
    if (auto out = step(e)) pending_.push_back(*out);
  kept_.clear();
  kept_.shrink_to_fit();
}

}  // namespace uwbloc::loc
