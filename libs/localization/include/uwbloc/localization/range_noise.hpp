// The range model a filter learns from the data (sigma=auto, bias=auto). Online statistics of a
// filter's own innovations do not identify it: the state follows a biased range as readily as
// the model learns the bias, and a lost filter learns its own error as noise. So the filters
// learn it from a batch: the range + odometry graph over the first seconds of the recording
// (variance-component estimate of the std, a bias per anchor when one stands out), and then
// use it as a fixed model.
#pragma once

#include <array>
#include <cmath>
#include <map>
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
  /// The learnt model into the run's statistics (estimated_noise, estimated_range_sigma).
  void report(EstimatorStatistics& stats) const;

 private:
  double sigma_;                               ///< the method's own std
  std::optional<double> learnt_sigma_;         ///< the learnt std, when one was learnt
  std::optional<double> learnt_scale_;         ///< the learnt scale, when one stood out
  std::map<int, NoiseEstimate> learnt_noise_;  ///< per anchor; biases zeroed when not used
};

}  // namespace uwbloc::loc
