#include "uwbloc/localization/methods/uwb_ekf_multitag.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "uwbloc/localization/methods/uwb_multitag.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/uwb/gates.hpp"
#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

namespace {
constexpr int kTheta = 4;  ///< the heading's index in the state
constexpr int kOmega = 5;

// The (x, y, theta) block of the state's covariance.
constexpr int kPoseIndex[3] = {0, 1, kTheta};
}  // namespace

std::unique_ptr<Estimator> makeUwbEkf(const UwbEkfMethodParams& params,
                                      const EstimatorContext& context) {
  if (params.tags == EkfTags::kAuto && context.robot_tags.size() >= 2)
    return std::make_unique<UwbEkfMultitag>(params, context);
  return std::make_unique<UwbEkf>(params.ekf, context);
}

UwbEkfMultitag::UwbEkfMultitag(const UwbEkfMethodParams& params, const EstimatorContext& context)
    : UwbEstimator(params.ekf.front, context, TagUse::kAll),
      params_(params),
      init_epochs_(params.ekf.epoch_window),
      noise_(params.ekf.front.sigmaValue()) {
  if (params.ekf.start == EkfStart::kStartPose) start_pose_ = context.initial_pose;
  params_.ekf.accel_psd = params.ekf.q.value.value_or(params.ekf.accel_psd);
  start_ = makeLearningStart(params.ekf.front.sigma, &params.ekf.q, params.ekf.learning, context);
}

double UwbEkfMultitag::rangeModel(const State& x, const Eigen::Vector3d& tag_on_robot,
                                  const Eigen::Vector3d& anchor,
                                  Eigen::Matrix<double, 1, 6>* jacobian) {
  Eigen::RowVector3d d_pose;
  const double h = uwb::predictRange(Eigen::Vector3d(x(0), x(1), x(kTheta)), tag_on_robot, anchor,
                                     jacobian ? &d_pose : nullptr);
  if (jacobian) {
    jacobian->setZero();
    for (int i = 0; i < 3; ++i) (*jacobian)(kPoseIndex[i]) = d_pose(i);
  }
  return h;
}

void UwbEkfMultitag::learn(const EstimatorStatistics& learnt) {
  learnRangeFilterNoise(learnt, params_.ekf, noise_, stats_);
}

double UwbEkfMultitag::rangeVariance(const AcceptedRange& r) const {
  const double sigma = params_.ekf.front.sigmaValue();
  return sigma * sigma * r.variance_scale;
}

void UwbEkfMultitag::reset() {
  initialised_ = false;
  quarantine_.clear();
  gated_in_a_row_ = 0;
  init_epochs_ = EpochBuffer(params_.ekf.epoch_window);
}

void UwbEkfMultitag::predictTo(double t) {
  const double dt = t - t_;
  if (dt <= 0.0) return;
  Eigen::Matrix4d f4, q4;
  constantVelocityModel(dt, params_.ekf.accel_psd, f4, q4, params_.ekf.velocity_tau);
  Covariance f = Covariance::Identity(), q = Covariance::Zero();
  f.topLeftCorner<4, 4>() = f4;
  q.topLeftCorner<4, 4>() = q4;
  f(kTheta, kOmega) = dt;
  const double w = params_.yaw_accel_psd;
  q(kTheta, kTheta) = w * dt * dt * dt / 3.0;
  q(kTheta, kOmega) = q(kOmega, kTheta) = w * dt * dt / 2.0;
  q(kOmega, kOmega) = w * dt;
  x_ = f * x_;
  x_(kTheta) = wrapAngle(x_(kTheta));
  p_ = f * p_ * f.transpose() + q;
  t_ = t;
}

bool UwbEkfMultitag::update(const AcceptedRange& r) {
  predictTo(r.measurement.t);
  Eigen::Matrix<double, 1, 6> h;
  const double z = rangeModel(x_, r.measurement.tag_on_robot, r.anchor, &h);
  const double variance = rangeVariance(r);
  kalman::Innovation<1> inn;
  inn.y(0) = r.measurement.range - z;
  inn.s(0, 0) = (h * p_ * h.transpose())(0, 0) + variance;
  const bool in_gate =
      uwb::ChiSquareGate(params_.ekf.gate).acceptSquared(inn.y(0) * inn.y(0) / inn.s(0, 0));
  if (!quarantine_.admit({r.measurement.anchor_id, r.measurement.tag_id}, inn.y(0), in_gate,
                         params_.ekf.readmit, readmitTolerance(params_.ekf), stats_))
    return false;
  kalman::josephUpdate<6, 1>(x_, p_, inn, h, Eigen::Matrix<double, 1, 1>(variance));
  x_(kTheta) = wrapAngle(x_(kTheta));
  return true;
}

// The first start at the start pose when there is one; otherwise, and after a restart, at the
// first epoch whose multi-tag Gauss-Newton fix fits within init_residual.
bool UwbEkfMultitag::initialise(const AcceptedRange& r) {
  x_.setZero();
  p_ = Covariance::Identity();  // 1 m/s, 1 rad/s
  if (start_pose_) {
    x_(0) = start_pose_->x();
    x_(1) = start_pose_->y();
    x_(kTheta) = start_pose_->z();
    const double sp = params_.ekf.start_sigma, sy = params_.start_sigma_yaw * M_PI / 180.0;
    p_(0, 0) = p_(1, 1) = sp * sp;
    p_(kTheta, kTheta) = sy * sy;
    start_pose_.reset();
    t_ = r.measurement.t;
  } else {
    const auto epoch = init_epochs_.add(r);
    if (!epoch) return false;
    const UwbMultitagParams gn;  // uwb-multitag's Huber threshold and iterations
    const auto fix = solveMultitag(*epoch, params_.ekf.front.sigmaValue(), gn.huber,
                                   gn.max_iterations, std::nullopt);
    if (!fix || fix->rms_residual > params_.ekf.init_residual) {
      ++stats_.events["init_fix_refused"];
      return false;
    }
    for (int i = 0; i < 3; ++i) {
      x_(kPoseIndex[i]) = fix->pose(i);
      for (int j = 0; j < 3; ++j) p_(kPoseIndex[i], kPoseIndex[j]) = fix->covariance(i, j);
    }
    t_ = epochTime(*epoch);
  }
  quarantine_.clear();
  initialised_ = true;
  gated_in_a_row_ = 0;
  return true;
}

PoseEstimate UwbEkfMultitag::output() const {
  PoseEstimate e;
  e.t = t_;
  e.pose = Eigen::Vector3d(x_(0), x_(1), x_(kTheta));
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) e.covariance(i, j) = p_(kPoseIndex[i], kPoseIndex[j]);
  e.heading_valid = p_(kTheta, kTheta) < kObservedHeadingStd * kObservedHeadingStd;
  return e;
}

std::optional<PoseEstimate> UwbEkfMultitag::doProcess(const Event& event) {
  return start_.process(event, learnt_, step_);
}

std::vector<PoseEstimate> UwbEkfMultitag::doFinishAll() { return start_.finish(learnt_, step_); }

std::optional<PoseEstimate> UwbEkfMultitag::doFinish() { return newestOfFinishAll(); }

std::optional<PoseEstimate> UwbEkfMultitag::step(const Event& event) {
  auto accepted = acceptRange(event);
  if (!accepted || !correctRange(*accepted, noise_)) return std::nullopt;
  if (initialised_ && params_.ekf.reinit_std > 0.0 &&
      predictedPositionStd(p_.topLeftCorner<4, 4>(), accepted->measurement.t - t_, params_.ekf) >
          params_.ekf.reinit_std) {
    ++stats_.events["reinitialised_after_outage"];
    reset();
  }
  if (!initialised_) {
    if (!initialise(*accepted)) return std::nullopt;
    return output();
  }
  const bool used = update(*accepted);
  gated_in_a_row_ = used ? 0 : gated_in_a_row_ + 1;
  if (gated_in_a_row_ >= params_.ekf.max_gated || !x_.allFinite() || !p_.allFinite()) {
    ++stats_.resets;
    reset();
    return std::nullopt;
  }
  return output();
}

}  // namespace uwbloc::loc
