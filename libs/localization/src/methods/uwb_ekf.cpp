#include "uwbloc/localization/methods/uwb_ekf.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "uwbloc/localization/registry.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

UwbEkf::UwbEkf(const UwbEkfParams& params, const EstimatorContext& context)
    : UwbEstimator(params.front, context),
      params_(params),
      init_epochs_(params.epoch_window),
      noise_(params.front.sigmaValue()) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
  if (params.start == EkfStart::kStartPose) start_pose_ = context.initial_pose;
  params_.accel_psd = params.q.value.value_or(params.accel_psd);
  start_ = makeLearningStart(params.front.sigma, &params.q, params.learning, context);
}

void learnRangeFilterNoise(const EstimatorStatistics& learnt, UwbEkfParams& params,
                           RangeNoiseModel& noise, EstimatorStatistics& stats) {
  noise.learnFrom(learnt, params.learning.calib_bias, params.front.sigma.isAuto());
  noise.report(stats);
  // The filter's std is then the corrected range's (the ranges are corrected as they come),
  // only ever widened; q only ever raised (range_noise.hpp).
  if (params.front.sigma.isAuto() && learnt.estimated_range_sigma)
    params.front.sigma.value = noise.widened(params.front.sigmaValue(), stats);
  learnAccelPsd(learnt, params.q, params.velocity_tau, params.accel_psd, stats);
  countLearnt(learnt, stats);
}

void UwbEkf::learn(const EstimatorStatistics& learnt) {
  learnRangeFilterNoise(learnt, params_, noise_, stats_);
}

void UwbEkf::reset() {
  initialised_ = false;
  quarantine_.clear();
  gated_in_a_row_ = 0;
  init_epochs_ = EpochBuffer(params_.epoch_window);
}

void UwbEkf::predictTo(double t) {
  kalman::predictConstantVelocity(x_, p_, t - t_, params_.accel_psd, params_.velocity_tau);
}

double UwbEkf::rangeModel(const Eigen::Vector4d& x, const AcceptedRange& r,
                          Eigen::Matrix<double, 1, 4>* hj) {
  const Eigen::Vector3d tag(x(0), x(1), r.measurement.tag_on_robot.z());
  const double h = std::max((tag - r.anchor).norm(), 1e-6);
  if (hj) *hj << (x(0) - r.anchor.x()) / h, (x(1) - r.anchor.y()) / h, 0.0, 0.0;
  return h;
}

UwbEkf::RangePrediction UwbEkf::predictRange(const AcceptedRange& r) {
  RangePrediction pred;
  pred.z = rangeModel(x_, r, &hj_);
  pred.s = (hj_ * p_ * hj_.transpose())(0, 0) + rangeVariance(r);
  return pred;
}

void UwbEkf::correctWithRange(const AcceptedRange& r, double y, const RangePrediction& pred) {
  kalman::Innovation<1> inn;
  inn.y(0) = y;
  inn.s(0, 0) = pred.s;
  kalman::josephUpdate<4, 1>(x_, p_, inn, hj_, Eigen::Matrix<double, 1, 1>(rangeVariance(r)));
}

double predictedPositionStd(const Eigen::Matrix4d& p, double dt, const UwbEkfParams& params) {
  Eigen::Matrix4d f, q;
  constantVelocityModel(std::max(0.0, dt), params.accel_psd, f, q, params.velocity_tau);
  const Eigen::Matrix2d pos = (f * p * f.transpose() + q).topLeftCorner<2, 2>();
  const double half_trace = 0.5 * pos.trace();
  const double det = pos.determinant();
  return std::sqrt(half_trace + std::sqrt(std::max(half_trace * half_trace - det, 0.0)));
}

double readmitTolerance(const UwbEkfParams& params) {
  return std::max(params.readmit_tol, 3.0 * params.front.sigmaValue());
}

PoseEstimate UwbEkf::output(const Eigen::Vector3d& tag_on_robot) const {
  return kalman::tagTrackPose(t_, x_.head<2>(), p_.topLeftCorner<2, 2>(), tag_on_robot,
                              heading_.heading());
}

// The first start at the start pose (at rest, position std start_sigma), when there is one;
// otherwise, and after divergence, at the first epoch that multilaterates (Gauss-Newton).
bool UwbEkf::initialise(const AcceptedRange& r) {
  if (start_pose_) {
    x_ << start_pose_->x(), start_pose_->y(), 0.0, 0.0;
    p_ = Eigen::Vector4d(params_.start_sigma * params_.start_sigma,
                         params_.start_sigma * params_.start_sigma, 1.0, 1.0)
             .asDiagonal();
    start_pose_.reset();
    t_ = r.measurement.t;
  } else {
    auto epoch = init_epochs_.add(r);
    if (!epoch) return false;
    const auto fix =
        consistentFix(*epoch, params_.front.sigmaValue(), params_.init_residual, stats_);
    if (!fix) return false;
    kalman::initialiseFromFix(*fix, x_, p_);
    t_ = epochTime(*epoch);
  }
  quarantine_.clear();
  initialised_ = true;
  gated_in_a_row_ = 0;
  onStart();
  return true;
}

std::optional<PoseEstimate> UwbEkf::doProcess(const Event& event) {
  return start_.process(event, learnt_, step_);
}

std::vector<PoseEstimate> UwbEkf::doFinishAll() { return start_.finish(learnt_, step_); }

std::optional<PoseEstimate> UwbEkf::doFinish() { return newestOfFinishAll(); }

std::optional<PoseEstimate> UwbEkf::step(const Event& event) {
  auto accepted = acceptRange(event);
  if (!accepted || !correctRange(*accepted, noise_)) return std::nullopt;

  if (initialised_ && params_.reinit_std > 0.0 &&
      predictedPositionStd(p_, accepted->measurement.t - t_, params_) > params_.reinit_std) {
    ++stats_.events["reinitialised_after_outage"];
    reset();
  }
  if (!initialised_) {
    if (!initialise(*accepted)) return std::nullopt;
    return output(accepted->measurement.tag_on_robot);
  }

  const bool used = updateWithRange(*accepted);
  // Every anchor disagreeing with the state for a while means the filter is lost.
  gated_in_a_row_ = used ? 0 : gated_in_a_row_ + 1;
  if (gated_in_a_row_ >= params_.max_gated) {
    ++stats_.resets;
    reset();
    return std::nullopt;
  }
  heading_.update(x_.tail<2>());
  return output(accepted->measurement.tag_on_robot);
}

bool UwbEkf::updateWithRange(const AcceptedRange& r) {
  if (r.measurement.t > t_) {
    predictTo(r.measurement.t);
    t_ = r.measurement.t;
  }
  const RangePrediction pred = predictRange(r);
  const double y = r.measurement.range - pred.z;
  const bool in_gate = uwb::ChiSquareGate(params_.gate).acceptSquared(y * y / pred.s);
  if (!admit(r.measurement.anchor_id, y, in_gate)) return false;
  correctWithRange(r, y, pred);
  return true;
}

bool RangeQuarantine::admit(const Link& link, double innovation, bool in_gate, int readmit,
                            double tolerance, EstimatorStatistics& stats) {
  auto q = held_.find(link);
  if (!in_gate) {
    countRejection(stats, uwb::toString(uwb::RejectReason::kInnovation), link.first);
    held_[link] = 0;
    return false;
  }
  if (q == held_.end()) return true;
  if (std::abs(innovation) <= tolerance && ++q->second >= readmit) {
    held_.erase(q);
    return true;
  }
  if (std::abs(innovation) > tolerance) q->second = 0;
  countRejection(stats, "quarantine", link.first);
  return false;
}

bool UwbEkf::admit(int id, double innovation, bool in_gate) {
  return quarantine_.admit({id, 0}, innovation, in_gate, params_.readmit, readmitTolerance(params_),
                           stats_);
}

}  // namespace uwbloc::loc
