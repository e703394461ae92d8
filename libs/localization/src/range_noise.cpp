#include "uwbloc/localization/range_noise.hpp"

#include "uwbloc/localization/graph/range_graph.hpp"

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

void RangeNoiseModel::report(EstimatorStatistics& stats) const {
  if (!learnt_noise_.empty()) stats.estimated_noise = learnt_noise_;
  if (learnt_sigma_) stats.estimated_range_sigma = learnt_sigma_;
  if (learnt_scale_) stats.estimated_range_scale = learnt_scale_;
}

}  // namespace uwbloc::loc
