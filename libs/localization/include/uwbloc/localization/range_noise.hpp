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

/// A range model per anchor: the bias to subtract and the std. Until learnt (or when fixed),
/// every anchor has no bias and the method's own std.
class RangeNoiseModel {
 public:
  explicit RangeNoiseModel(double sigma) : sigma_(sigma) {}
  /// Takes a learnt model: `noise` per anchor (bias, applied only when `use_bias`) and the
  /// std (none: keep the method's own).
  void learn(const std::map<int, NoiseEstimate>& noise, bool use_bias, std::optional<double> sigma);
  double bias(int anchor) const {
    const auto it = learnt_noise_.find(anchor);
    return it == learnt_noise_.end() ? 0.0 : it->second.bias;
  }
  double sigma() const { return learnt_sigma_.value_or(sigma_); }
  /// The learnt model into the run's statistics (estimated_noise, estimated_range_sigma).
  void report(EstimatorStatistics& stats) const;

 private:
  double sigma_;                               ///< the method's own std
  std::optional<double> learnt_sigma_;         ///< the learnt std, when one was learnt
  std::map<int, NoiseEstimate> learnt_noise_;  ///< per anchor; biases zeroed when not used
};

}  // namespace uwbloc::loc
