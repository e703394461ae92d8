#include "uwbloc/localization/methods/point_filters.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc {

namespace {

using Range1 = Eigen::Matrix<double, 1, 1>;

}  // namespace

void checkHinfRatio(double hinf) {
  if (hinf != 0.0 && !(hinf > 1.0))
    throw ParamError("parameter 'hinf' = " + std::to_string(hinf) +
                     " must be 0 (plain CKF) or above 1: it multiplies the smallest gamma for "
                     "which the H-infinity bound exists");
}

template <int N>
UwbCkfT<N>::UwbCkfT(const UwbCkfParams& params, const EstimatorContext& context)
    : UwbEkfT<N>(params.ekf, context), hinf_(params.hinf), fold_blind_(params.fold_blind) {
  checkHinfRatio(hinf_);
}

template <int N>
typename UwbCkfT<N>::RangePrediction UwbCkfT<N>::predictRange(const AcceptedRange& r) {
  this->boundHeadingSpread(p_);
  const auto points = kalman::cubaturePoints<N>(x_, p_);
  fold_.reset();
  if (fold_blind_)
    fold_ = rangeFold(points, x_, r, std::sqrt(this->rangeVariance(r)), this->sideSigmas());
  if (fold_) {
    const auto pred = Base::predictRange(r);
    pzz_ = pred.s - this->rangeVariance(r);
    return pred;
  }
  moments_ = kalman::propagate<N, 1>(
      points, x_, [&](const kalman::Vec<N>& x) { return Range1(Base::rangeModel(x, r)); });
  pzz_ = moments_.pzz(0, 0);
  return {moments_.z(0), pzz_ + this->rangeVariance(r)};
}

template <int N>
void UwbCkfT<N>::cubatureCorrect(double y, double r_var) {
  if (fold_) {
    this->foldCorrect(y, r_var, *fold_);
  } else if (hinf_ > 0.0) {
    kalman::Mat<N, N> position = kalman::Mat<N, N>::Zero();  // the bound is on (x, y)
    position(0, 0) = position(1, 1) = 1.0;
    const double gamma = kalman::hinfCubatureUpdate<N, 1>(x_, p_, moments_, Range1(y),
                                                          Range1(r_var), hinf_, position);
    if (gamma == 0.0) ++stats_.events["hinf_bound_infeasible"];
  } else {
    kalman::cubatureUpdate<N, 1>(x_, p_, moments_, Range1(y), Range1(r_var));
  }
}

template <int N>
void UwbCkfT<N>::correctWithRange(const AcceptedRange& r, double y, const RangePrediction&) {
  cubatureCorrect(y, this->rangeVariance(r));
}

double iggIIIFactor(double v, double k0, double k1) {
  if (v <= k0) return 1.0;
  if (v > k1) return std::numeric_limits<double>::infinity();
  const double shape = (k1 - k0) / (k1 - v);
  return v / k0 * shape * shape;
}

template <int N>
UwbIahCkfT<N>::UwbIahCkfT(const UwbIahCkfParams& params, const EstimatorContext& context)
    : UwbCkfT<N>(params.ckf, context), iah_(params) {
  if (!(params.k1 > params.k0))
    throw ParamError("parameter 'k1' must exceed 'k0' (IGG-III: k0 < k1)");
}

template <int N>
bool UwbIahCkfT<N>::updateWithRange(const AcceptedRange& r) {
  if (r.measurement.t > this->t_) {
    this->predictTo(r.measurement.t);
    this->t_ = r.measurement.t;
  }
  // The statistics are the link's: the anchor's with one tag, the anchor-tag pair's with several
  // (each pair has its own antenna delay and blockage).
  const auto link = this->link(r);
  auto [it, fresh] = links_.try_emplace(link);
  auto& stat = it->second;
  if (fresh) {
    stat.R(0, 0) = this->rangeVariance();
    stat.k = iah_.priorSteps();
  }
  const auto pred = this->predictRange(r);
  const double innovation = r.measurement.range - pred.z;
  const double e = innovation - stat.r(0);  // less the link's estimated bias
  const double pzz = this->predictedRangeVariance();
  const double v = std::abs(e) / std::sqrt(pzz + stat.R(0, 0));
  // The NLOS threshold under the robust factor: small innovations always keep R.
  const bool suspect = std::abs(e) > iah_.nlos_threshold;
  const double factor = suspect ? iggIIIFactor(v, iah_.k0, iah_.k1) : 1.0;
  if (!this->admit(r, e, std::isfinite(factor))) return false;
  if (factor > 1.0) ++stats_.events["robust_factor_inflated"];
  this->cubatureCorrect(e, factor * stat.R(0, 0) * r.variance_scale);
  if (factor == 1.0) {
    // The Sage-Husa statistics (eq. 16, 24). R̂ from the innovation, e^2 - P_zz with the points'
    // P_zz for H P H^T; or (the default) from the post-fit residual at the updated mean, less
    // the same bias, ε^2 + H P_k H^T with the range's Jacobian there (Mohamed & Schwarz 1999,
    // kalman/sage_husa.hpp): between ranges a second apart the constant-velocity prediction's
    // P_zz outgrows the ranges' noise, and from the innovation R̂ sat at its floor (σ/2) for
    // 673 of the MRPT demo's ranges.
    double r_sample = e * e - pzz;
    if (iah_.r_from != SageHusaRFrom::kInnovation) {
      typename Base::Jacobian hj;
      const double residual = r.measurement.range - Base::rangeModel(this->x_, r, &hj) - stat.r(0);
      r_sample = residual * residual + (hj * this->p_ * hj.transpose())(0, 0);
    }
    const double d = kalman::sageHusaWeight(iah_.forgetting, stat.k);
    if (iah_.bias) {
      // Bounded: the learning start has removed a constant bias before the filter runs, so what
      // r̂ should follow is a drift within the range noise. Unbounded it followed the filter's own
      // position error on CARMEN intel+uwb (anchor 3 at +0.93 m by the end, up to 4.9 m; the
      // MRPT demo's and Hanyang LOS A1's stay within 0.18 and 0.10 m): 1.867 -> 1.000 m there
      // at 2 sigma, no other benchmark column moved.
      const double cap = iah_.bias_max.value.value_or(2.0 * params_.front.sigmaValue());
      stat.r(0) = std::clamp((1.0 - d) * stat.r(0) + d * innovation, -cap, cap);
      if (std::abs(stat.r(0)) == cap) ++stats_.events["bias_at_bias_max"];
    }
    stat.R(0, 0) = (1.0 - d) * stat.R(0, 0) + d * r_sample;
    const double floor = iah_.r_floor.value.value_or(0.5 * params_.front.sigmaValue());
    if (stat.R(0, 0) < floor * floor) {
      stat.R(0, 0) = floor * floor;
      ++stats_.events["r_kept_positive"];
    }
    ++stat.k;
    this->reportNoise(link, {stat.r(0), std::sqrt(stat.R(0, 0)), stat.k - iah_.priorSteps()});
  }
  return true;
}

template <int N>
UwbSrukfT<N>::UwbSrukfT(const UwbSrukfParams& params, const EstimatorContext& context)
    : UwbEkfT<N>(params.ekf, context), sr_(params) {
  if (!(params.alpha * params.alpha * (N + params.kappa) > 0.0))
    throw ParamError(
        "parameters 'ut_alpha', 'ut_kappa': n + lambda = alpha^2 (n + kappa) must "
        "be positive (n = " +
        std::to_string(N) + ")");
}

template <int N>
void UwbSrukfT<N>::onStart() {
  s_ = kalman::lowerSquareRoot<N>(p_);
}

template <int N>
void UwbSrukfT<N>::predictTo(double t) {
  Covariance f, q;
  this->transition(t - this->t_, f, q);
  const bool ok = kalman::sqrtUnscentedPredict<N>(
      x_, s_, [&](const State& x) { return State(f * x); }, kalman::lowerSquareRoot<N>(q),
      sr_.alpha, sr_.beta, sr_.kappa);
  if (!ok) ++stats_.events["sqrt_rebuilt"];
  p_ = s_ * s_.transpose();
}

template <int N>
typename UwbSrukfT<N>::RangePrediction UwbSrukfT<N>::predictRange(const AcceptedRange& r) {
  if (this->boundHeadingSpread(p_)) s_ = kalman::lowerSquareRoot<N>(p_);
  points_ = kalman::unscentedPoints<N>(x_, s_, sr_.alpha, sr_.beta, sr_.kappa);
  fold_.reset();
  if (sr_.fold_blind)
    fold_ = rangeFold(points_, x_, r, std::sqrt(this->rangeVariance(r)), this->sideSigmas());
  if (fold_) return Base::predictRange(r);
  moments_ = kalman::propagate<N, 1>(
      points_, x_, [&](const State& x) { return Range1(Base::rangeModel(x, r)); });
  return {moments_.z(0), std::max(moments_.pzz(0, 0), 0.0) + this->rangeVariance(r)};
}

template <int N>
void UwbSrukfT<N>::correctWithRange(const AcceptedRange& r, double y, const RangePrediction&) {
  if (fold_) {
    this->foldCorrect(y, this->rangeVariance(r), *fold_);
    s_ = kalman::lowerSquareRoot<N>(p_);
    return;
  }
  const bool ok = kalman::sqrtUnscentedUpdate<N, 1>(x_, s_, points_, moments_, Range1(y),
                                                    Range1(std::sqrt(this->rangeVariance(r))));
  if (!ok) ++stats_.events["sqrt_rebuilt"];
  p_ = s_ * s_.transpose();
}

template class UwbCkfT<4>;
template class UwbCkfT<6>;
template class UwbIahCkfT<4>;
template class UwbIahCkfT<6>;
template class UwbSrukfT<4>;
template class UwbSrukfT<6>;

}  // namespace uwbloc::loc
