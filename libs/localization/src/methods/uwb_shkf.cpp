#include "uwbloc/localization/methods/uwb_shkf.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "uwbloc/localization/kalman/sage_husa.hpp"
#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc {
namespace {
/// Appends `sample` to a statistic's window, keeps its last `length` samples, returns their mean.
double windowMean(std::deque<double>& window, double sample, std::size_t length) {
  window.push_back(sample);
  while (window.size() > length) window.pop_front();
  return std::accumulate(window.begin(), window.end(), 0.0) / static_cast<double>(window.size());
}
}  // namespace

template <int N>
UwbShkfT<N>::UwbShkfT(const UwbShkfParams& params, const EstimatorContext& context)
    : UwbEkfT<N>(params.ekf, context), sh_(params) {
  if (!(params.c1 > params.c0)) throw ParamError("parameter 'c1' must exceed 'c0'");
  if (params.beta.value && (*params.beta.value < 0.0 || *params.beta.value > 1.0))
    throw ParamError("parameter 'beta' must be in [0, 1] or auto");
}

template <int N>
double UwbShkfT<N>::adaptiveFactor(double change, double c0, double c1) {
  if (change <= c0) return 0.0;
  if (change > c1) return 1.0;
  return (change - c0) / (c1 - c0);
}

template <int N>
void UwbShkfT<N>::keepAtFloor(double& r, double floor) {
  if (r >= floor * floor) return;
  r = floor * floor;
  ++stats_.events["r_kept_positive"];
}

template <int N>
bool UwbShkfT<N>::updateWithRange(const AcceptedRange& r) {
  const int id = r.measurement.anchor_id;
  const double p_nlos = r.measurement.nlos_probability.value_or(0.0);
  if (p_nlos > sh_.p_reject) {
    this->countRejection("nlos_probability", id);
    return false;
  }
  Covariance f, q;
  this->transition(std::max(0.0, this->dt(r.measurement.t)), f, q);
  t_ = std::max(t_, r.measurement.t);
  const typename Base::State x_pred = f * x_;
  const Covariance fpf = f * p_ * f.transpose();
  const auto link = this->link(r);
  auto [it, fresh] = links_.try_emplace(link);
  AnchorStatistic& a = it->second;
  if (fresh) a.r = a.c_exp = a.r_exp = this->rangeVariance();
  x_ = x_pred;
  p_ = fpf + q;
  typename Base::Jacobian hj;
  const double innovation = r.measurement.range - Base::rangeModel(x_, r, &hj);
  const double e = innovation - a.bias;
  const double hpfh = (hj * fpf * hj.transpose())(0, 0);
  const double hqh = (hj * q * hj.transpose())(0, 0);
  // The gate and the quarantine on the unfaded prediction: a refused range leaves the
  // statistics alone (an NLOS burst would otherwise become the anchor's noise).
  const bool in_gate = uwb::ChiSquareGate(params_.gate).acceptSquared(e * e / (hpfh + hqh + a.r));
  if (!this->admit(r, e, in_gate)) return false;

  // The two innovation statistics and their adaptive mix.
  const double d = kalman::sageHusaWeight(sh_.forgetting, a.k);
  const double change = std::abs(e - a.last_e) / std::sqrt(std::max(a.c_exp, 1e-12));
  a.c_exp = (1.0 - d) * a.c_exp + d * e * e;
  const auto window = static_cast<std::size_t>(
      std::clamp(sh_.n0 + sh_.kn * std::abs(a.last_e), double(sh_.n0), 10.0 * sh_.n0));
  const double c_win = windowMean(a.window, e * e, window);
  const double beta = sh_.beta.value ? *sh_.beta.value
                      : a.k == 0     ? 0.0
                                     : adaptiveFactor(change, sh_.c0, sh_.c1);
  const double c = (1.0 - beta) * a.c_exp + beta * c_win;
  // The fading factor from C_k, then R̂: from C_k (the innovation form, used in this update)
  // or, by default, from this update's residual (used from the next range on).
  const double lambda = hpfh > 0.0 ? std::clamp((c - hqh - a.r) / hpfh, 1.0, sh_.fading_max) : 1.0;
  if (lambda > 1.0) ++stats_.events["fading_inflated"];
  p_ = lambda * fpf + q;
  const double floor = sh_.r_floor.value.value_or(0.5 * params_.front.sigmaValue());
  const bool from_residual = sh_.r_from != SageHusaRFrom::kInnovation;
  if (!from_residual) {
    a.r = c - (hj * p_ * hj.transpose())(0, 0);
    // Until the anchor's statistics hold n0 innovations, R̂ is kept at least the model's: the
    // first innovations are mostly the start's uncertainty, and C - H P H^T from a few of them
    // fell to the floor (greenhouse R1: an overconfident filter that gated 612 ranges, 3.93 m).
    if (a.k + 1 < static_cast<long>(sh_.n0) && a.r < this->rangeVariance()) {
      a.r = this->rangeVariance();
      ++stats_.events["r_kept_at_model_until_n0"];
    }
    keepAtFloor(a.r, floor);
  }
  if (sh_.bias) a.bias = (1.0 - d) * a.bias + d * innovation;
  a.last_e = e;
  ++a.k;
  // The update, with the range's NLOS probability widening its noise.
  const Eigen::Matrix<double, 1, 1> rv(a.r / (1.0 - p_nlos));
  const auto inn = kalman::innovate<N, 1>(p_, Eigen::Matrix<double, 1, 1>(e), hj, rv);
  const typename Base::State x_prior = x_;
  kalman::josephUpdate<N, 1>(x_, p_, inn, hj, rv);
  if (from_residual) {
    // E[ε^2 + H P_k H^T] = R, two positive terms (sage_husa.hpp), through the same exponential
    // and windowed statistics and the same β as C_k.
    const double r_k = kalman::residualNoiseSample<N, 1>(Eigen::Matrix<double, 1, 1>(e), hj,
                                                         x_ - x_prior, p_)(0, 0);
    a.r_exp = (1.0 - d) * a.r_exp + d * r_k;
    a.r = (1.0 - beta) * a.r_exp + beta * windowMean(a.r_window, r_k, window);
    keepAtFloor(a.r, floor);
  }
  this->reportNoise(link, {a.bias, std::sqrt(a.r), a.k});
  return true;
}

template class UwbShkfT<4>;
template class UwbShkfT<6>;

}  // namespace uwbloc::loc
