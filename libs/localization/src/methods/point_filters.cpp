#include "uwbloc/localization/methods/point_filters.hpp"

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

UwbCkf::UwbCkf(const UwbCkfParams& params, const EstimatorContext& context)
    : UwbEkf(params.ekf, context), hinf_(params.hinf) {
  checkHinfRatio(hinf_);
}

UwbEkf::RangePrediction UwbCkf::predictRange(const AcceptedRange& r) {
  const auto points = kalman::cubaturePoints<4>(x_, p_);
  moments_ = kalman::propagate<4, 1>(points, x_, [&](const Eigen::Vector4d& x) {
    return Range1(rangeModel(x, r));
  });
  return {moments_.z(0), moments_.pzz(0, 0) + rangeVariance(r)};
}

void UwbCkf::cubatureCorrect(double y, double r_var) {
  if (hinf_ > 0.0) {
    const Eigen::Matrix4d position = Eigen::Vector4d(1, 1, 0, 0).asDiagonal();
    const double gamma = kalman::hinfCubatureUpdate<4, 1>(x_, p_, moments_, Range1(y),
                                                          Range1(r_var), hinf_, position);
    if (gamma == 0.0) ++stats_.events["hinf_bound_infeasible"];
  } else {
    kalman::cubatureUpdate<4, 1>(x_, p_, moments_, Range1(y), Range1(r_var));
  }
}

void UwbCkf::correctWithRange(const AcceptedRange& r, double y, const RangePrediction&) {
  cubatureCorrect(y, rangeVariance(r));
}

double iggIIIFactor(double v, double k0, double k1) {
  if (v <= k0) return 1.0;
  if (v > k1) return std::numeric_limits<double>::infinity();
  const double shape = (k1 - k0) / (k1 - v);
  return v / k0 * shape * shape;
}

UwbIahCkf::UwbIahCkf(const UwbIahCkfParams& params, const EstimatorContext& context)
    : UwbCkf(params.ckf, context), iah_(params) {
  if (!(params.k1 > params.k0))
    throw ParamError("parameter 'k1' must exceed 'k0' (IGG-III: k0 < k1)");
}

bool UwbIahCkf::updateWithRange(const AcceptedRange& r) {
  if (r.measurement.t > t_) {
    predictTo(r.measurement.t);
    t_ = r.measurement.t;
  }
  const int id = r.measurement.anchor_id;
  auto [it, fresh] = anchors_.try_emplace(id);
  auto& stat = it->second;
  if (fresh) {
    stat.R(0, 0) = rangeVariance();
    stat.k = iah_.priorSteps();
  }
  const RangePrediction pred = predictRange(r);
  const double innovation = r.measurement.range - pred.z;
  const double e = innovation - stat.r(0);  // less the anchor's estimated bias
  const double pzz = moments_.pzz(0, 0);
  const double v = std::abs(e) / std::sqrt(pzz + stat.R(0, 0));
  // The NLOS threshold under the robust factor: small innovations always keep R.
  const bool suspect = std::abs(e) > iah_.nlos_threshold;
  const double factor = suspect ? iggIIIFactor(v, iah_.k0, iah_.k1) : 1.0;
  if (!admit(id, e, std::isfinite(factor))) return false;
  if (factor > 1.0) ++stats_.events["robust_factor_inflated"];
  cubatureCorrect(e, factor * stat.R(0, 0) * r.variance_scale);
  if (factor == 1.0) {
    // The Sage-Husa statistics (eq. 16, 24), with the points' P_zz for H P H^T.
    const double d = kalman::sageHusaWeight(iah_.forgetting, stat.k);
    if (iah_.bias) stat.r(0) = (1.0 - d) * stat.r(0) + d * innovation;
    stat.R(0, 0) = (1.0 - d) * stat.R(0, 0) + d * (e * e - pzz);
    const double floor = iah_.r_floor.value.value_or(0.5 * params_.front.sigmaValue());
    if (stat.R(0, 0) < floor * floor) {
      stat.R(0, 0) = floor * floor;
      ++stats_.events["r_kept_positive"];
    }
    ++stat.k;
    stats_.estimated_noise[id] = {stat.r(0), std::sqrt(stat.R(0, 0)), stat.k - iah_.priorSteps()};
  }
  return true;
}

UwbSrukf::UwbSrukf(const UwbSrukfParams& params, const EstimatorContext& context)
    : UwbEkf(params.ekf, context), sr_(params) {
  if (!(params.alpha * params.alpha * (4.0 + params.kappa) > 0.0))
    throw ParamError("parameters 'ut_alpha', 'ut_kappa': n + lambda = alpha^2 (n + kappa) must "
                     "be positive (n = 4)");
}

void UwbSrukf::onStart() { s_ = kalman::lowerSquareRoot<4>(p_); }

void UwbSrukf::predictTo(double t) {
  Eigen::Matrix4d f, q;
  constantVelocityModel(t - t_, params_.accel_psd, f, q, params_.velocity_tau);
  const bool ok = kalman::sqrtUnscentedPredict<4>(
      x_, s_, [&](const Eigen::Vector4d& x) { return Eigen::Vector4d(f * x); },
      kalman::lowerSquareRoot<4>(q), sr_.alpha, sr_.beta, sr_.kappa);
  if (!ok) ++stats_.events["sqrt_rebuilt"];
  p_ = s_ * s_.transpose();
}

UwbEkf::RangePrediction UwbSrukf::predictRange(const AcceptedRange& r) {
  points_ = kalman::unscentedPoints<4>(x_, s_, sr_.alpha, sr_.beta, sr_.kappa);
  moments_ = kalman::propagate<4, 1>(points_, x_, [&](const Eigen::Vector4d& x) {
    return Range1(rangeModel(x, r));
  });
  return {moments_.z(0), std::max(moments_.pzz(0, 0), 0.0) + rangeVariance(r)};
}

void UwbSrukf::correctWithRange(const AcceptedRange& r, double y, const RangePrediction&) {
  const bool ok = kalman::sqrtUnscentedUpdate<4, 1>(x_, s_, points_, moments_, Range1(y),
                                                    Range1(std::sqrt(rangeVariance(r))));
  if (!ok) ++stats_.events["sqrt_rebuilt"];
  p_ = s_ * s_.transpose();
}

}  // namespace uwbloc::loc
