#include "uwbloc/localization/methods/uwb_kf.hpp"

#include <Eigen/Dense>

namespace uwbloc::loc {

UwbKf::UwbKf(const UwbKfParams& params, const EstimatorContext& context)
    : UwbEstimator(params.front, context.anchors), params_(params), epochs_(params.epoch_window) {
  if (params_.solver != "ls" && params_.solver != "gn" && params_.solver != "chan")
    throw ParamError("uwb-kf: parameter 'solver' must be ls, gn or chan, got '" + params_.solver +
                     "'");
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

std::optional<PoseEstimate> UwbKf::doProcess(const Event& event) {
  const auto accepted = acceptRange(event);
  if (!accepted) return std::nullopt;
  if (auto epoch = epochs_.add(*accepted)) return onEpoch(*epoch);
  return std::nullopt;
}

std::optional<PoseEstimate> UwbKf::doFinish() {
  if (auto epoch = epochs_.flush()) return onEpoch(*epoch);
  return std::nullopt;
}

std::optional<PoseEstimate> UwbKf::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const auto planar = toPlanar(epoch, params_.front.sigma);
  const uwb::Fix fix = params_.solver == "gn"     ? uwb::solveGaussNewton(planar)
                       : params_.solver == "chan" ? uwb::solveChan(planar)
                                                  : uwb::solveLinearLS(planar);
  if (!fix.ok()) {
    countRejection(std::string("epoch_") + uwb::toString(fix.status));
    return std::nullopt;
  }
  const double t = epochTime(epoch);
  const Eigen::Vector2d& z = fix.position;
  const Eigen::Matrix2d& r = fix.covariance;

  auto initialise = [&] {
    x_ << z, 0.0, 0.0;
    p_.setZero();
    p_.topLeftCorner<2, 2>() = r;
    p_(2, 2) = p_(3, 3) = 1.0;  // 1 m/s velocity uncertainty
    t_ = t;
    initialised_ = true;
    gated_in_a_row_ = 0;
  };
  const bool consistent = fix.residual_norm <= params_.init_residual;
  if (!initialised_) {
    if (!consistent) {
      countRejection("init_inconsistent_fix");
      return std::nullopt;
    }
    initialise();
  } else {
    // Predict: x = F x, P = F P F^T + Q.
    Eigen::Matrix4d f, q;
    constantVelocityModel(std::max(0.0, t - t_), params_.accel_psd, f, q, params_.velocity_tau);
    x_ = f * x_;
    p_ = f * p_ * f.transpose() + q;
    t_ = std::max(t_, t);
    // Update with H = [I 0]: innovation y = z - H x, S = H P H^T + R.
    const Eigen::Vector2d y = z - x_.head<2>();
    const Eigen::Matrix2d s = p_.topLeftCorner<2, 2>() + r;
    const double d2 = y.dot(s.ldlt().solve(y));
    if (d2 > params_.gate) {
      countRejection("kf_innovation_gate");
      if (++gated_in_a_row_ >= params_.max_gated && consistent) {
        ++stats_.resets;
        initialise();
      }
    } else {
      gated_in_a_row_ = 0;
      // K = P H^T S^-1; Joseph form P = (I - K H) P (I - K H)^T + K R K^T.
      const Eigen::Matrix<double, 4, 2> k = p_.leftCols<2>() * s.inverse();
      Eigen::Matrix<double, 2, 4> h = Eigen::Matrix<double, 2, 4>::Zero();
      h.leftCols<2>().setIdentity();
      const Eigen::Matrix4d ikh = Eigen::Matrix4d::Identity() - k * h;
      x_ += k * y;
      p_ = ikh * p_ * ikh.transpose() + k * r * k.transpose();
    }
  }
  const double heading = heading_.update(x_.tail<2>());
  PoseEstimate est;
  est.t = t_;
  est.pose << robotFromTag(x_.head<2>(), epoch.front().measurement.tag_on_robot, heading), heading;
  est.covariance.setZero();
  est.covariance.topLeftCorner<2, 2>() = p_.topLeftCorner<2, 2>();
  est.covariance(2, 2) = M_PI * M_PI;
  est.heading_valid = false;
  return est;
}

}  // namespace uwbloc::loc
