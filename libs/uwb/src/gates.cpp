#include "uwbloc/uwb/gates.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace uwbloc::uwb {

namespace {
constexpr std::pair<RejectReason, const char*> kReasonNames[] = {
    {RejectReason::kNonFinite, "non_finite"},
    {RejectReason::kZero, "zero_range"},
    {RejectReason::kNegative, "negative_range"},
    {RejectReason::kBeyondMax, "beyond_max_range"},
    {RejectReason::kBelowHeight, "below_height_difference"},
    {RejectReason::kUnknownAnchor, "unknown_anchor"},
    {RejectReason::kIncrement, "increment_queue"},
    {RejectReason::kChiSquare, "chi_square"},
    {RejectReason::kThreeSigma, "three_sigma"},
    {RejectReason::kInnovation, "innovation_gate"},
    {RejectReason::kTimeBackwards, "time_backwards"},
    {RejectReason::kOtherTag, "other_tag"},
    {RejectReason::kNlosModel, "nlos_model"},
    {RejectReason::kSecondaryTag, "secondary_tag"},
    {RejectReason::kMobileMoving, "mobile_anchor_moving"},
};
}  // namespace

const char* toString(RejectReason r) {
  for (const auto& [reason, name] : kReasonNames)
    if (reason == r) return name;
  return "unknown";
}

std::optional<RejectReason> checkValidity(double range, const ValidityParams& params) {
  if (!std::isfinite(range)) return RejectReason::kNonFinite;
  if (range < 0.0) return RejectReason::kNegative;
  if (range <= params.min_range) return RejectReason::kZero;
  if (range > params.max_range) return RejectReason::kBeyondMax;
  return std::nullopt;
}

bool IncrementQueueGate::accept(int anchor_id, double t, double range, int tag_id) {
  const int n = std::clamp(params_.queue_length, 1, 32);
  auto [it, inserted] = state_.try_emplace({anchor_id, tag_id});
  AnchorState& s = it->second;
  if (inserted) {
    s.last_range = range;
    s.last_t = t;
    return true;
  }
  const double inc = range - s.last_range;
  double mean_abs = 0.0;
  for (int j = 0; j < s.count; ++j) mean_abs += std::abs(s.increments[static_cast<size_t>(j)]);
  if (s.count > 0) mean_abs /= s.count;
  const double dt = std::max(0.0, t - s.last_t);
  const double y =
      params_.zeta * mean_abs + params_.max_speed * dt + params_.noise_floor - std::abs(inc);
  if (y > 0.0) {
    s.increments[static_cast<size_t>(s.head)] = inc;  // overwrites the increment of t-n+1
    s.head = (s.head + 1) % n;
    s.count = std::min(s.count + 1, n);
    s.last_range = range;
    s.last_t = t;
    s.consecutive_rejects = 0;
    return true;
  }
  if (++s.consecutive_rejects >= params_.max_consecutive_rejects) {
    s = AnchorState{};
    s.last_range = range;
    s.last_t = t;
    ++reseeds_;
  }
  return false;
}

bool ChiSquareGate::accept(double residual, double variance) const {
  if (!(variance > 0.0) || !std::isfinite(residual)) return false;
  return residual * residual / variance <= threshold_;
}

bool ThreeSigmaGate::accept(int anchor_id, double residual) {
  if (!std::isfinite(residual)) return false;
  const int n = std::clamp(params_.window, 2, 128);
  Window& w = windows_[anchor_id];
  if (w.count >= params_.min_samples) {
    double mean = 0.0;
    for (int j = 0; j < w.count; ++j) mean += w.values[static_cast<size_t>(j)];
    mean /= w.count;
    double var = 0.0;
    for (int j = 0; j < w.count; ++j) {
      const double d = w.values[static_cast<size_t>(j)] - mean;
      var += d * d;
    }
    const double sigma = std::max(std::sqrt(var / (w.count - 1)), params_.min_sigma);
    if (std::abs(residual - mean) > params_.k * sigma) return false;
  }
  w.values[static_cast<size_t>(w.head)] = residual;
  w.head = (w.head + 1) % n;
  w.count = std::min(w.count + 1, n);
  return true;
}

}  // namespace uwbloc::uwb
