#include "uwbloc/localization/methods/uwb_ekf.hpp"

#include <Eigen/Dense>

namespace uwbloc::loc {

UwbEkf::UwbEkf(const UwbEkfParams& params, const EstimatorContext& context)
    : UwbEstimator(params.front, context.anchors),
      params_(params),
      init_epochs_(params.epoch_window) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

void UwbEkf::reset() {
  initialised_ = false;
  quarantine_.clear();
  gated_in_a_row_ = 0;
  init_epochs_ = EpochBuffer(params_.epoch_window);
}

void UwbEkf::predict(double t) {
  // x = F x, P = F P F^T + Q (constant velocity).
  const double dt = t - t_;
  if (dt <= 0.0) return;
  Eigen::Matrix4d f, q;
  constantVelocityModel(dt, params_.accel_psd, f, q, params_.velocity_tau);
  x_ = f * x_;
  p_ = f * p_ * f.transpose() + q;
  t_ = t;
}

bool UwbEkf::inGate(const AcceptedRange& r, double* innovation, Eigen::RowVector4d* hj,
                    double* s) const {
  // h(x) = || (x, y, z_tag) - anchor ||, H = [dx/h, dy/h, 0, 0].
  const Eigen::Vector3d tag(x_(0), x_(1), r.measurement.tag_on_robot.z());
  const Eigen::Vector3d diff = tag - r.anchor;
  const double h = std::max(diff.norm(), 1e-6);
  *hj << diff.x() / h, diff.y() / h, 0.0, 0.0;
  *innovation = r.measurement.range - h;
  // S = H P H^T + R; Mahalanobis gate on the scalar innovation.
  *s = (*hj) * p_ * hj->transpose() + params_.front.sigma * params_.front.sigma;
  return (*innovation) * (*innovation) / (*s) <= params_.gate;
}

void UwbEkf::update(double innovation, const Eigen::RowVector4d& hj, double s) {
  const double var_r = params_.front.sigma * params_.front.sigma;
  const Eigen::Vector4d k = p_ * hj.transpose() / s;
  x_ += k * innovation;
  // Joseph form keeps P symmetric positive definite.
  const Eigen::Matrix4d ikh = Eigen::Matrix4d::Identity() - k * hj;
  p_ = ikh * p_ * ikh.transpose() + var_r * k * k.transpose();
}

PoseEstimate UwbEkf::output(const Eigen::Vector3d& tag_on_robot) const {
  PoseEstimate est;
  est.t = t_;
  const double heading = heading_.heading();
  est.pose << robotFromTag(x_.head<2>(), tag_on_robot, heading), heading;
  est.covariance.setZero();
  est.covariance.topLeftCorner<2, 2>() = p_.topLeftCorner<2, 2>();
  est.covariance(2, 2) = M_PI * M_PI;
  est.heading_valid = false;
  return est;
}

std::optional<PoseEstimate> UwbEkf::doProcess(const Event& event) {
  const auto accepted = acceptRange(event);
  if (!accepted) return std::nullopt;

  if (!initialised_) {
    // Start from the first epoch that multilaterates (Gauss-Newton).
    auto epoch = init_epochs_.add(*accepted);
    if (!epoch) return std::nullopt;
    const uwb::Fix fix = uwb::solveGaussNewton(toPlanar(*epoch, params_.front.sigma));
    if (!fix.ok()) {
      countRejection(std::string("init_") + uwb::toString(fix.status));
      return std::nullopt;
    }
    if (fix.residual_norm > params_.init_residual) {
      countRejection("init_inconsistent_fix");  // some range of the epoch is wrong
      return std::nullopt;
    }
    quarantine_.clear();
    x_ << fix.position, 0.0, 0.0;
    p_.setZero();
    p_.topLeftCorner<2, 2>() = fix.covariance;
    p_(2, 2) = p_(3, 3) = 1.0;
    t_ = epochTime(*epoch);
    initialised_ = true;
    gated_in_a_row_ = 0;
    return output(accepted->measurement.tag_on_robot);
  }

  predict(accepted->measurement.t);
  double innovation = 0.0, s = 0.0;
  Eigen::RowVector4d hj;
  const int id = accepted->measurement.anchor_id;
  // A quarantined anchor must agree within max(readmit_tol, 3 sigma) to count towards readmission.
  const double tolerance = std::max(params_.readmit_tol, 3.0 * params_.front.sigma);
  const bool in_gate = inGate(*accepted, &innovation, &hj, &s);
  auto q = quarantine_.find(id);
  bool used = false;
  if (!in_gate) {
    countRejection(uwb::RejectReason::kInnovation, id);
    quarantine_[id] = 0;
  } else if (q != quarantine_.end() && std::abs(innovation) > tolerance) {
    q->second = 0;
    countRejection("quarantine", id);
  } else if (q == quarantine_.end() || ++q->second >= params_.readmit) {
    if (q != quarantine_.end()) quarantine_.erase(q);
    update(innovation, hj, s);
    used = true;
  } else {
    countRejection("quarantine", id);
  }
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

}  // namespace uwbloc::loc
