#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc {

void RangeNoiseModel::learn(const std::map<int, NoiseEstimate>& noise, bool use_bias,
                            std::optional<double> sigma) {
  learnt_noise_ = noise;
  bias_.clear();
  for (auto& [id, n] : learnt_noise_) {
    if (!use_bias) n.bias = 0.0;
    bias_[id] = n.bias;
  }
  if (sigma && std::isfinite(*sigma) && *sigma > 0.0) {
    sigma_ = *sigma;
    sigma_learnt_ = true;
  }
  learnt_ = true;
}

void RangeNoiseModel::report(EstimatorStatistics& stats) const {
  if (!learnt_) return;
  stats.estimated_noise = learnt_noise_;
  if (sigma_learnt_) stats.estimated_range_sigma = sigma_;
}

}  // namespace uwbloc::loc
