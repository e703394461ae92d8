// The range model a filter learns from the data (sigma=auto, bias=auto). Online statistics of a
// filter's own innovations do not identify it: the state follows a biased range as readily as
// the model learns the bias, and a lost filter learns its own error as noise. So the filters
// learn it from a batch: the range + odometry graph over the first seconds of the recording
// (variance-component estimate of the std, a bias per anchor when one stands out), and then
// use it as a fixed model.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/params.hpp"

namespace uwbloc::loc {

namespace graph {
struct ScaleEvidence;  // graph/range_graph.hpp
}

/// Per-anchor range bias: never, always, or (auto) when the data shows one.
enum class BiasMode { kOff, kOn, kAuto };
constexpr std::array<EnumName<BiasMode>, 3> enumNames(BiasMode) {
  return {{{BiasMode::kOff, "0"}, {BiasMode::kOn, "1"}, {BiasMode::kAuto, "auto"}}};
}

/// The median of v (the upper one for an even count; 0 when empty), NaNs left out: they have no
/// order, and std::nth_element given one may read past the range.
inline double medianOf(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return std::isnan(x); }), v.end());
  if (v.empty()) return 0.0;
  const auto m = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), m, v.end());
  return *m;
}

/// The median of the last `window` values added: a ring buffer, whose copy for the median reuses
/// its storage.
class WindowMedian {
 public:
  explicit WindowMedian(size_t window) : window_(window) {}
  void add(double v) {
    if (values_.size() < window_)
      values_.push_back(v);
    else
      values_[count_ % window_] = v;
    ++count_;
  }
  size_t size() const { return values_.size(); }
  double median() const {
    scratch_.assign(values_.begin(), values_.end());
    if (scratch_.empty()) return 0.0;
    const auto m = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
    std::nth_element(scratch_.begin(), m, scratch_.end());
    return *m;
  }

 private:
  size_t window_;
  size_t count_ = 0;
  std::vector<double> values_;
  mutable std::vector<double> scratch_;  ///< median()'s workspace, kept to reuse its memory
};

/// bias=auto's test on an anchor's offsets (range minus predicted distance): a bias stands out
/// when the median offset of each half of the span, in time, exceeds the offsets' robust spread
/// (a bias below the noise costs less left alone than estimated) and the two agree within it
/// (an offset that drifts is a slow error, not a bias).
inline bool biasStandsOut(double median_first_half, double median_second_half,
                          double robust_sigma) {
  return std::abs(median_first_half) > robust_sigma &&
         std::abs(median_second_half) > robust_sigma &&
         std::abs(median_first_half - median_second_half) < robust_sigma;
}

/// scale=auto's test on the range residuals' slope against the distance within anchors
/// (ScaleEvidence: over the span [0] and over each half of it, in time [1], [2]). A scale stands
/// out when the slope over the span is beyond 3 of its standard errors, explains at least a
/// quarter of the residuals' variance within anchors (a smaller one is not worth a parameter:
/// on the MRPT demo the slope is 0.5 % and explains 6 %; on Plaza2 it is 5.4 % and explains
/// 60 %), and the two halves agree within 3 standard errors of their difference (a slope that
/// changes along the run is not a fixed scale).
bool scaleStandsOut(const graph::ScaleEvidence& e);

/// The test where the path has no odometry to hold its shape (motion=cv), which then bends to
/// take up most of a scale's slope: the range std learnt without the scale and the one learnt
/// (from the start) with it. It stands out when it explains at least a quarter of the variance,
/// the same share as scaleStandsOut's (Plaza2: 2.39 m against 0.58 m, 94 %).
inline bool scaleExplains(double spread_without, double spread_with) {
  return spread_without > 0.0 &&
         1.0 - (spread_with * spread_with) / (spread_without * spread_without) >= 0.25;
}

/// The learning start's keys, shared by the range filters and the per-epoch solvers.
struct RangeLearningParams {
  /// A range bias per anchor learnt at the start: auto, since the learner drops biases that
  /// widen the anchors' residual spreads (the MRPT demo's faulty beacon passed for biases of
  /// -0.20 / -0.38 / +0.22 m, uwb-ekf 0.710 m instead of 0.163 m, before that test).
  BiasMode calib_bias = BiasMode::kAuto;
  double calib = 60.0;  ///< seconds of ranges the model is learnt from at the start (0: none)

  template <class V>
  void visit(V&& v) {
    v("calib_bias", calib_bias,
      "a range bias per anchor learnt at the start: auto (the default: when one stands out or "
      "explains the variance, and does not widen the anchors' residual spreads), 0 or 1");
    v("calib", calib,
      "seconds of ranges at the start that the range model (sigma, bias, scale) and q are "
      "learnt from (graph-uwb over them), before they are used; 0: none");
  }
};

/// Learnt models shared between runs (the methods of a compare or a benchmark): a learning start
/// whose learner, context and events are those of an earlier one given the same cache takes that
/// one's statistics instead of solving the same graph again. A run gets it through
/// EstimatorContext::learning_cache; without one it solves its own start. Thread-safe: a run
/// that asks for a model another run is solving waits for it. Keeps the last `kept` models.
class LearningCache {
 public:
  explicit LearningCache(size_t kept = 8) : kept_(kept) {}
  /// The statistics under `key`: an earlier run's (`*reused` true), or `solve`'s, kept for the
  /// next. When `solve` throws, those waiting get the error and a later run solves it again.
  EstimatorStatistics get(const std::string& key, const std::function<EstimatorStatistics()>& solve,
                          bool* reused);

 private:
  std::mutex mutex_;
  std::deque<std::pair<std::string, std::shared_future<EstimatorStatistics>>> models_;
  size_t kept_;
};

/// A method took a learnt model (`learnt`, the learner's statistics): counts range_model_learnt
/// in `stats`, and range_model_reused when the model came from an earlier identical start.
void countLearnt(const EstimatorStatistics& learnt, EstimatorStatistics& stats);

/// The q a constant-velocity filter with velocity decay `tau` takes from a learnt one, when `q`
/// is auto, into `accel_psd` (the q in force; stats: q_raised, estimated_accel_psd):
/// the learnt q is constant velocity's (short-term accelerations); a decaying velocity holds a
/// per-axis spread of q tau / 2 only, so q is raised until that is the path's own (half its mean
/// squared speed per axis), q = ms / tau. Learning only raises q above `q_now`: a minute of
/// motion is a small sample, and a stiffer filter is the side that diverges (on the MRPT demo q
/// 0.086 instead of 0.1 turns uwb-hinf-ckf from 0.336 to 1.99 m and uwb-shkf from 0.713 to
/// 1.83 m, as a faulty beacon captures them or not).
void learnAccelPsd(const EstimatorStatistics& learnt, const AutoDouble& q, double tau,
                   double& accel_psd, EstimatorStatistics& stats);

/// A filter's start with a learnt model: the events of the first `span` seconds are kept and
/// given to a learning method (a batch smoother) as well; when the span is over (or the stream
/// ends) the learner's statistics go to the filter, and the kept events are filtered. Their
/// estimates are queued and handed out one per later event (or at the end), so a caller still
/// gets at most one per event, each with its own time, with a lag that the events without an
/// estimate drain.
class LearningStart {
 public:
  using Learnt = std::function<void(const EstimatorStatistics&)>;
  using Step = std::function<std::optional<PoseEstimate>(const Event&)>;
  LearningStart() = default;
  /// No learner: every event goes straight to the filter.
  /// With a `cache`, `share_key` is the learner's identity (its spec and context); the learner
  /// then takes the kept events only at the end, and not at all when a start with the same key
  /// and the same events has been learnt into that cache (its statistics are taken instead).
  LearningStart(std::unique_ptr<Estimator> learner, double span, std::string share_key = {},
                std::shared_ptr<LearningCache> cache = nullptr)
      : learner_(std::move(learner)),
        span_(span),
        share_key_(std::move(share_key)),
        cache_(std::move(cache)) {}
  bool learning() const { return learner_ != nullptr; }
  /// The events kept while learning; during the Learnt callback, every event of the start.
  const std::vector<Event>& kept() const { return kept_; }
  /// One event: kept while learning (ending the learning when its span is over), else stepped;
  /// returns the oldest queued estimate.
  std::optional<PoseEstimate> process(const Event& event, const Learnt& learnt, const Step& step);
  /// The end of the stream: ends the learning if it is still on; every queued estimate.
  std::vector<PoseEstimate> finish(const Learnt& learnt, const Step& step);

 private:
  void end(const Learnt& learnt, const Step& step);
  /// The learnt model may come from the cache (a cache and a key to find it by).
  bool shared() const { return cache_ && !share_key_.empty(); }
  /// The learner's statistics after the kept events.
  EstimatorStatistics solve();
  /// The same, taken from an identical start in the cache when there is one.
  EstimatorStatistics sharedStatistics();
  std::unique_ptr<Estimator> learner_;
  double span_ = 0.0;
  std::string share_key_;
  std::shared_ptr<LearningCache> cache_;
  std::optional<double> t0_;
  std::vector<Event> kept_;
  std::deque<PoseEstimate> pending_;
};

/// A method's learning start: graph-uwb with the method's own sigma, calib_bias and
/// (when the method has one) q, as its learner. None (no learner: every event goes straight to
/// the filter) when `learning.calib` is 0 or nothing is left to learn (sigma fixed, calib_bias
/// off, q fixed or absent). With the context's learning cache the learnt model is shared: a
/// learning start whose learner, context and events are those of an earlier one (the other
/// methods of a compare or a benchmark) takes that one's statistics instead of solving the same
/// graph again.
LearningStart makeLearningStart(const AutoDouble& sigma, const AutoDouble* q,
                                const RangeLearningParams& learning,
                                const EstimatorContext& context);

/// A range model per anchor: the bias to subtract and the std. Until learnt (or when fixed),
/// every anchor has no bias and the method's own std.
class RangeNoiseModel {
 public:
  explicit RangeNoiseModel(double sigma) : sigma_(sigma) {}
  /// Takes a learnt model: `noise` per anchor (bias, applied only when `use_bias`), the std
  /// (none: keep the method's own) and the range scale (none: no scale).
  void learn(const std::map<int, NoiseEstimate>& noise, bool use_bias, std::optional<double> sigma,
             std::optional<double> scale = std::nullopt);
  double bias(int anchor) const {
    const auto it = learnt_noise_.find(anchor);
    return it == learnt_noise_.end() ? 0.0 : it->second.bias;
  }
  double scale() const { return learnt_scale_.value_or(0.0); }
  /// The distance a range measures under the model z = (1 + scale) d + bias.
  double correct(int anchor, double range) const {
    return (range - bias(anchor)) / (1.0 + scale());
  }
  /// The std of a corrected range.
  double sigma() const { return learnt_sigma_.value_or(sigma_) / (1.0 + scale()); }
  /// Takes a learner's statistics (a LearningStart's): the biases when `calib_bias` is on, or
  /// auto and the learner found one; the std when `sigma_auto`; the scale when one stood out.
  void learnFrom(const EstimatorStatistics& learnt, BiasMode calib_bias, bool sigma_auto);
  /// The method's std after learning (sigma=auto): the corrected range's, but only wider than
  /// `sigma_now`, as a tighter gate is the side that fails (Hanyang NLOS B3 learns 0.047 m and
  /// uwb-ekf scores 0.530 m with it against 0.386 m at 0.15; the simulated AGV room learns
  /// 0.115 m, 0.417 against 0.158 m; Plaza2 learns 0.53 m, which it needs). A std kept is
  /// counted (sigma_kept_at_start).
  double widened(double sigma_now, EstimatorStatistics& stats) const;
  /// The learnt model into the run's statistics (estimated_noise, estimated_range_sigma).
  void report(EstimatorStatistics& stats) const;

 private:
  double sigma_;                               ///< the method's own std
  std::optional<double> learnt_sigma_;         ///< the learnt std, when one was learnt
  std::optional<double> learnt_scale_;         ///< the learnt scale, when one stood out
  std::map<int, NoiseEstimate> learnt_noise_;  ///< per anchor; biases zeroed when not used
};

}  // namespace uwbloc::loc
