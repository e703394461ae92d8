#include "uwbloc/localization/methods/uwb_akf.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "uwbloc/localization/motion_models.hpp"

namespace uwbloc::loc {

UwbAkf::UwbAkf(const UwbAkfParams& params, const EstimatorContext& context)
    : UwbKf(params.kf, context), akf_(params) {}

void UwbAkf::start(const uwb::Fix& fix) {
  UwbKf::start(fix);
  process_ = {};
  measurement_ = {};
  measurement_.R = fix.covariance;
  process_.mean = akf_.estimatesMean(true);
  measurement_.mean = akf_.estimatesMean(false);
  measurement_.from_residual = akf_.rFromResidual();
  // The starting statistics count as akf_.priorSteps() steps already taken (UwbAkfParams).
  measurement_.k = process_.k = akf_.priorSteps();
}

void UwbAkf::learn(const EstimatorStatistics& learnt) {
  UwbKf::learn(learnt);
  if (akf_.q_floor)
    learnAccelPsd(learnt, params_.q, params_.velocity_tau, params_.accel_psd, stats_);
}

bool UwbAkf::predictAndUpdate(const uwb::Fix& fix, double dt) {
  Eigen::Matrix4d f, q;
  constantVelocityModel(dt, params_.accel_psd, f, q, params_.velocity_tau);
  if (process_.k == akf_.priorSteps()) {
    process_.Q = q;  // Q̂_0: the model's over the first interval (no step taken yet)
  } else if (akf_.q_floor) {
    // Q̂ >= the model's Q over this interval (UwbAkfParams::q_floor): what Q̂ holds beyond it is
    // kept, what falls short of it is raised.
    Eigen::Matrix4d above = process_.Q - q;
    if (kalman::projectEigenvalues<4>(above, 0.0)) ++stats_.events["q_kept_at_model"];
    process_.Q = q + above;
  }
  Eigen::Matrix<double, 2, 4> h = Eigen::Matrix<double, 2, 4>::Zero();
  h.leftCols<2>().setIdentity();
  // R̂'s eigenvalues at or above the fix's variance along its best-determined axis
  // (UwbAkfParams::r_floor_fix), else the positivity guard alone.
  double r_floor = akf_.r_floor;
  if (akf_.r_floor_fix) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(fix.covariance);
    r_floor = std::max(r_floor, std::sqrt(std::max(0.0, eig.eigenvalues()(0))));
  }
  const auto step = kalman::sageHusaStep<4, 2>(x_, p_, process_, measurement_, f, fix.position, h,
                                               akf_.forgetting, akf_.gamma, r_floor);
  if (step.diverged) ++stats_.events["divergence_inflated"];
  if (step.r_projected) ++stats_.events["r_kept_positive"];
  if (step.q_projected) ++stats_.events["q_kept_positive"];
  return true;
}

namespace {

// uwb-ekf's parameters from the adaptive filter's (the EKF-only ones at uwb-ekf's defaults).
UwbEkfParams ekfParams(const UwbAkfParams& p) {
  UwbEkfParams e;
  e.front = p.kf.fix.front;
  e.epoch_window = p.kf.fix.epoch_window;
  e.q = p.kf.q;
  e.accel_psd = p.kf.accel_psd;
  e.learning = p.kf.fix.learning;
  e.velocity_tau = p.kf.velocity_tau;
  e.init_residual = p.kf.fix.init_residual;
  e.tags = p.kf.fix.tags;
  e.yaw_accel_psd = p.kf.fix.yaw_accel_psd;
  e.start = p.start;
  return e;
}

}  // namespace

template <int N>
UwbAkfRanges<N>::UwbAkfRanges(const UwbAkfParams& params, const EstimatorContext& context)
    : UwbEkfT<N>(ekfParams(params), context), akf_(params) {}

template <int N>
void UwbAkfRanges<N>::onStart() {
  links_.clear();
}

template <int N>
bool UwbAkfRanges<N>::updateWithRange(const AcceptedRange& r) {
  // The process statistics are the constant-velocity model's over this interval: adapted range
  // by range (q̂ the mean correction, Q̂ from K e e^T K^T + P - F P F^T), they drifted on the
  // demo, where each range corrects one direction only (uwb-akf 8.1 m, uwb-iakf 1036 m).
  typename Base::Covariance f;
  kalman::SageHusaProcess<N> process;  // q̂ = 0, Q̂ the model's
  this->transition(std::max(0.0, this->dt(r.measurement.t)), f, process.Q);
  const auto pred = kalman::sageHusaPredict<N>(x_, p_, process, f);
  t_ = std::max(t_, r.measurement.t);
  typename Base::Jacobian hj;
  const double predicted = Base::rangeModel(x_, r, &hj);
  const auto link = this->link(r);
  auto [it, fresh] = links_.try_emplace(link);
  auto& anchor = it->second;
  if (fresh) {
    anchor.R(0, 0) = params_.front.sigmaValue() * params_.front.sigmaValue();
    anchor.mean = akf_.estimatesMean(false);
    anchor.k = akf_.priorSteps();
    anchor.from_residual = akf_.rFromResidual();
  }
  const double innovation = r.measurement.range - predicted;
  // uwb-ekf's gate and quarantine (UwbEkfT::admit) on the innovation less the anchor's bias: a
  // refused range leaves the statistics alone (an NLOS burst would otherwise become the anchor's
  // noise). The gate's R is the adaptive R̂ but never below the method's sigma^2: R̂ may fall
  // under the noise the gate allows for, and a gate tighter than uwb-ekf's drops good ranges
  // and, through the quarantine, the ranges after them (Hanyang NLOS A1: 1.027 m, against
  // 0.705 m with this floor).
  const double e = innovation - anchor.r(0);
  const double s =
      (hj * p_ * hj.transpose())(0, 0) + std::max(anchor.R(0, 0), this->rangeVariance(r));
  const bool in_gate = uwb::ChiSquareGate(params_.gate).acceptSquared(e * e / s);
  if (!this->admit(r, e, in_gate)) return false;
  const auto out = kalman::sageHusaUpdate<N, 1>(x_, p_, pred, nullptr, anchor,
                                                Eigen::Matrix<double, 1, 1>(innovation), hj,
                                                akf_.forgetting, akf_.gamma, akf_.r_floor);
  if (out.diverged) ++stats_.events["divergence_inflated"];
  if (out.r_projected) ++stats_.events["r_kept_positive"];
  // The anchor's range model as the filter now sees it: r̂ its bias, sqrt(R̂) its std.
  this->reportNoise(link, {anchor.r(0), std::sqrt(anchor.R(0, 0)), anchor.k - akf_.priorSteps()});
  return true;
}

template class UwbAkfRanges<4>;
template class UwbAkfRanges<6>;

std::unique_ptr<Estimator> makeUwbAkf(const UwbAkfParams& params, const EstimatorContext& context) {
  if (params.mode == AkfMode::kRanges)
    return makeRangeFilter<UwbAkfRanges>(params, params.kf.fix.tags, context);
  return std::make_unique<UwbAkf>(params, context);
}

}  // namespace uwbloc::loc
