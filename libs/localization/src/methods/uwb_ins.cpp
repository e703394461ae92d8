#include "uwbloc/localization/methods/uwb_ins.hpp"

#include <cmath>
#include <limits>

#include "uwbloc/localization/kalman/cubature.hpp"
#include "uwbloc/localization/methods/point_filters.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::loc {

namespace {

using Vec8 = Eigen::Matrix<double, 8, 1>;

Vec8 pack(const InsState& s) {
  Vec8 x;
  x << s.p, s.v, s.yaw, s.gyro_bias, s.accel_bias;
  return x;
}

InsState unpack(const Vec8& x) {
  InsState s;
  s.p = x.segment<2>(0);
  s.v = x.segment<2>(2);
  s.yaw = wrapAngle(x(4));
  s.gyro_bias = x(5);
  s.accel_bias = x.segment<2>(6);
  return s;
}

constexpr double kOutputPeriod = 0.1;  ///< [s] between estimates from the IMU alone

}  // namespace

UwbIns::UwbIns(const UwbInsParams& params, const EstimatorContext& context)
    // Range mode predicts each range through its tag's lever arm and the heading, so every tag
    // of the robot helps; fix mode multilaterates one tag point per epoch.
    : UwbEstimator(params.front, context,
                   params.mode == InsMode::kRanges ? TagUse::kAll : TagUse::kPrimary),
      params_(params),
      start_pose_(context.initial_pose),
      epochs_(params.epoch_window),
      detector_(params.still_window, params.still_acc, params.still_gyro, params.still_rate) {
  checkHinfRatio(params.hinf);
  if (!(params.k1 > params.k0))
    throw ParamError("parameter 'k1' must exceed 'k0' (IGG-III: k0 < k1)");
}

void UwbIns::reset() {
  initialised_ = false;
  gated_in_a_row_ = 0;
  epochs_ = EpochBuffer(params_.epoch_window);
}

PoseEstimate UwbIns::output() const {
  PoseEstimate est;
  est.t = t_;
  est.pose << s_.p, s_.yaw;
  est.covariance.setZero();
  est.covariance.topLeftCorner<2, 2>() = p_.topLeftCorner<2, 2>();
  est.covariance(2, 2) = p_(4, 4);
  est.covariance(0, 2) = est.covariance(2, 0) = p_(0, 4);
  est.covariance(1, 2) = est.covariance(2, 1) = p_(1, 4);
  est.heading_valid = p_(4, 4) < std::pow(10.0 * M_PI / 180.0, 2);
  return est;
}

bool UwbIns::initialise(const AcceptedRange& r) {
  tag_on_robot_ = r.measurement.tag_on_robot;
  p_.setZero();
  if (start_pose_) {
    s_ = InsState{};
    s_.p = start_pose_->head<2>();
    s_.yaw = start_pose_->z();
    p_.diagonal() << 0.25, 0.25, 1.0, 1.0, std::pow(5.0 * M_PI / 180.0, 2), 1e-4, 2.5e-3, 2.5e-3;
    start_pose_.reset();
    t_ = r.measurement.t;
  } else {
    auto epoch = epochs_.add(r);
    if (!epoch) return false;
    const auto fix =
        consistentFix(*epoch, params_.front.sigmaValue(), params_.init_residual, stats_);
    if (!fix) return false;
    s_ = InsState{};
    s_.p = fix->position;  // the lever arm is unknown until the heading is
    p_.topLeftCorner<2, 2>() = fix->covariance;
    p_.topLeftCorner<2, 2>().diagonal().array() += tag_on_robot_.head<2>().squaredNorm();
    p_.diagonal().tail<6>() << 1.0, 1.0, M_PI * M_PI, 1e-4, 2.5e-3, 2.5e-3;
    t_ = epochTime(*epoch);
  }
  epochs_ = EpochBuffer(params_.epoch_window);
  initialised_ = true;
  gated_in_a_row_ = 0;
  return true;
}

void UwbIns::correct(const Vec8& dx) { s_ = unpack(pack(s_) + dx); }

template <int M>
void UwbIns::pseudoUpdate(const Eigen::Matrix<double, M, 1>& y,
                          const Eigen::Matrix<double, M, 8>& h,
                          const Eigen::Matrix<double, M, M>& r) {
  const auto inn = kalman::innovate<8, M>(p_, y, h, r);
  Vec8 dx = Vec8::Zero();
  kalman::josephUpdate<8, M>(dx, p_, inn, h, r);
  correct(dx);
}

std::optional<PoseEstimate> UwbIns::onImu(const ImuSample& imu) {
  if (!imu.accel.allFinite() || !std::isfinite(imu.gyro_z) || !std::isfinite(imu.t)) {
    countRejection("non_finite_imu");
    return std::nullopt;
  }
  detector_.add(imu);
  if (!initialised_) return std::nullopt;
  const double dt = imu.t - t_;
  if (!(dt > 0.0)) {
    if (dt < 0.0) countRejection("imu_time_backwards");
    return std::nullopt;
  }
  Eigen::Matrix<double, 8, 8> q = Eigen::Matrix<double, 8, 8>::Zero();
  const double qa = params_.accel_noise * params_.accel_noise;
  q.block<2, 2>(0, 0).diagonal().setConstant(qa * dt * dt * dt / 3.0);
  q.block<2, 2>(0, 2).diagonal().setConstant(qa * dt * dt / 2.0);
  q.block<2, 2>(2, 0).diagonal().setConstant(qa * dt * dt / 2.0);
  q.block<2, 2>(2, 2).diagonal().setConstant(qa * dt);
  q(4, 4) = params_.gyro_noise * params_.gyro_noise * dt;
  q(5, 5) = params_.gyro_bias_walk * params_.gyro_bias_walk * dt;
  q(6, 6) = q(7, 7) = params_.accel_bias_walk * params_.accel_bias_walk * dt;
  if (params_.filter == InsFilter::kCkf) {
    // The points through the mechanisation, the heading kept unwrapped across them.
    Vec8 x = pack(s_);
    kalman::cubaturePredict<8>(
        x, p_,
        [&](const Vec8& pt) {
          Vec8 out = pack(mechanise(unpack(pt), imu, dt));
          out(4) = pt(4) + (imu.gyro_z - pt(5)) * dt;
          return out;
        },
        q);
    s_ = unpack(x);
  } else {
    Eigen::Matrix<double, 8, 8> f;
    s_ = mechanise(s_, imu, dt, &f);
    p_ = f * p_ * f.transpose() + q;
  }
  const double last = t_;
  t_ = imu.t;
  if (params_.zupt && detector_.still()) {
    Eigen::Matrix<double, 2, 8> h = Eigen::Matrix<double, 2, 8>::Zero();
    h(0, 2) = h(1, 3) = 1.0;
    pseudoUpdate<2>(-s_.v, h, Eigen::Matrix2d::Identity() * 1e-4);  // v = 0 within 1 cm/s
    ++stats_.events["zupt"];
    if (params_.zaru && detector_.notTurning(s_.gyro_bias)) {
      Eigen::Matrix<double, 1, 8> hz = Eigen::Matrix<double, 1, 8>::Zero();
      hz(0, 5) = 1.0;  // the rate measured at rest is the bias
      const double rv = params_.still_gyro * params_.still_gyro * 0.01;
      pseudoUpdate<1>(Eigen::Matrix<double, 1, 1>(detector_.meanRate() - s_.gyro_bias), hz,
                      Eigen::Matrix<double, 1, 1>(rv));
      ++stats_.events["zaru"];
    }
  }
  // An estimate every kOutputPeriod from the INS alone (through UWB gaps).
  if (std::floor(t_ / kOutputPeriod) != std::floor(last / kOutputPeriod)) return output();
  return std::nullopt;
}

bool UwbIns::updateRangeCubature(const AcceptedRange& r) {
  const Eigen::Vector2d lever = r.measurement.tag_on_robot.head<2>();
  const Vec8 x0 = pack(s_);
  const auto points = kalman::cubaturePoints<8>(x0, p_);
  const auto m = kalman::propagate<8, 1>(points, x0, [&](const Vec8& x) {
    const Eigen::Vector2d tag = x.head<2>() + rotation(x(4)) * lever;
    const Eigen::Vector3d d(tag.x() - r.anchor.x(), tag.y() - r.anchor.y(),
                            r.measurement.tag_on_robot.z() - r.anchor.z());
    return Eigen::Matrix<double, 1, 1>(std::max(d.norm(), 1e-6));
  });
  const double sigma = params_.front.sigmaValue();
  double rv = sigma * sigma * r.variance_scale;
  const double y = r.measurement.range - m.z(0);
  const double v = std::abs(y) / std::sqrt(m.pzz(0, 0) + rv);
  if (params_.robust && std::abs(y) > params_.nlos_threshold) {
    const double factor = iggIIIFactor(v, params_.k0, params_.k1);
    if (!std::isfinite(factor)) {
      countRejection(uwb::RejectReason::kInnovation, r.measurement.anchor_id);
      return false;
    }
    if (factor > 1.0) ++stats_.events["robust_factor_inflated"];
    rv *= factor;
  } else if (!uwb::ChiSquareGate(params_.gate).acceptSquared(v * v)) {
    countRejection(uwb::RejectReason::kInnovation, r.measurement.anchor_id);
    return false;
  }
  Vec8 x = x0;
  const Eigen::Matrix<double, 1, 1> ym(y), rm(rv);
  if (params_.hinf > 0.0) {
    Eigen::Matrix<double, 8, 8> position = Eigen::Matrix<double, 8, 8>::Zero();
    position(0, 0) = position(1, 1) = 1.0;
    if (kalman::hinfCubatureUpdate<8, 1>(x, p_, m, ym, rm, params_.hinf, position) == 0.0)
      ++stats_.events["hinf_bound_infeasible"];
  } else {
    kalman::cubatureUpdate<8, 1>(x, p_, m, ym, rm);
  }
  s_ = unpack(x);
  return true;
}

bool UwbIns::updateRange(const AcceptedRange& r) {
  if (params_.filter == InsFilter::kCkf) return updateRangeCubature(r);
  const Eigen::Matrix2d rot = rotation(s_.yaw);
  const Eigen::Vector2d lever = r.measurement.tag_on_robot.head<2>();
  const Eigen::Vector3d tag((s_.p + rot * lever).x(), (s_.p + rot * lever).y(),
                            r.measurement.tag_on_robot.z());
  const Eigen::Vector3d diff = tag - r.anchor;
  const double h = std::max(diff.norm(), 1e-6);
  Eigen::Matrix<double, 1, 8> hj = Eigen::Matrix<double, 1, 8>::Zero();
  hj(0, 0) = diff.x() / h;
  hj(0, 1) = diff.y() / h;
  hj(0, 4) = diff.head<2>().dot(rotationDerivative(s_.yaw) * lever) / h;
  const double sigma = params_.front.sigmaValue();
  const Eigen::Matrix<double, 1, 1> rv(sigma * sigma * r.variance_scale);
  const auto inn =
      kalman::innovate<8, 1>(p_, Eigen::Matrix<double, 1, 1>(r.measurement.range - h), hj, rv);
  if (!kalman::inGate(inn, uwb::ChiSquareGate(params_.gate))) {
    countRejection(uwb::RejectReason::kInnovation, r.measurement.anchor_id);
    return false;
  }
  Vec8 dx = Vec8::Zero();
  kalman::josephUpdate<8, 1>(dx, p_, inn, hj, rv);
  correct(dx);
  return true;
}

bool UwbIns::updateFix(const uwb::Fix& fix, const Eigen::Vector3d& tag_on_robot) {
  const Eigen::Vector2d lever = tag_on_robot.head<2>();
  Eigen::Matrix<double, 2, 8> h = Eigen::Matrix<double, 2, 8>::Zero();
  h.leftCols<2>().setIdentity();
  h.col(4) = rotationDerivative(s_.yaw) * lever;
  const Eigen::Vector2d y = fix.position - (s_.p + rotation(s_.yaw) * lever);
  const auto inn = kalman::innovate<8, 2>(p_, y, h, fix.covariance);
  // The 1-dof gate carried to 2 dof at the same tail probability (9 -> 11.8 for 3 sigma).
  const double threshold = params_.gate * 11.83 / 9.0;
  if (!kalman::inGate(inn, uwb::ChiSquareGate(threshold))) {
    countRejection("fix_innovation_gate");
    return false;
  }
  Vec8 dx = Vec8::Zero();
  kalman::josephUpdate<8, 2>(dx, p_, inn, h, fix.covariance);
  correct(dx);
  return true;
}

std::optional<PoseEstimate> UwbIns::doProcess(const Event& event) {
  if (const auto* imu = std::get_if<ImuSample>(&event)) return onImu(*imu);
  const auto accepted = acceptRange(event);
  if (!accepted) return std::nullopt;
  if (!initialised_) {
    if (!initialise(*accepted)) return std::nullopt;
    return output();
  }
  bool used = false;
  if (params_.mode == InsMode::kRanges) {
    used = updateRange(*accepted);
  } else {
    auto epoch = epochs_.add(*accepted);
    if (!epoch) return std::nullopt;
    // Every solvable epoch is used (the gate judges it), however large its residual.
    const auto fix = consistentFix(*epoch, params_.front.sigmaValue(),
                                   std::numeric_limits<double>::infinity(), stats_, "epoch_");
    if (!fix) return std::nullopt;
    used = updateFix(*fix, accepted->measurement.tag_on_robot);
  }
  gated_in_a_row_ = used ? 0 : gated_in_a_row_ + 1;
  if (gated_in_a_row_ >= params_.max_gated) {
    ++stats_.resets;
    reset();
    return std::nullopt;
  }
  return output();
}

}  // namespace uwbloc::loc
