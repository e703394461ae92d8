#include "uwbloc/localization/ins.hpp"

#include <cmath>

#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::loc {

InsState mechanise(const InsState& s, const ImuSample& imu, double dt,
                   Eigen::Matrix<double, 8, 8>* jacobian) {
  const Eigen::Matrix2d r = rotation(s.yaw);
  const Eigen::Vector2d f = imu.accel - s.accel_bias;
  const Eigen::Vector2d a = r * f;
  InsState out = s;
  out.yaw = wrapAngle(s.yaw + (imu.gyro_z - s.gyro_bias) * dt);
  out.p = s.p + s.v * dt + 0.5 * a * dt * dt;
  out.v = s.v + a * dt;
  if (jacobian) {
    auto& j = *jacobian;
    j.setIdentity();
    j.block<2, 2>(0, 2) = Eigen::Matrix2d::Identity() * dt;
    const Eigen::Matrix2d dr = rotationDerivative(s.yaw);
    j.block<2, 1>(0, 4) = 0.5 * dt * dt * dr * f;
    j.block<2, 2>(0, 6) = -0.5 * dt * dt * r;
    j.block<2, 1>(2, 4) = dt * dr * f;
    j.block<2, 2>(2, 6) = -dt * r;
    j(4, 5) = -dt;
  }
  return out;
}

void StationarityDetector::add(const ImuSample& imu) {
  samples_.push_back(imu);
  while (!samples_.empty() && samples_.front().t < imu.t - window_) samples_.pop_front();
}

namespace {

template <class F>
std::pair<double, double> meanVariance(const std::deque<ImuSample>& samples, F&& value) {
  double sum = 0.0, sq = 0.0;
  for (const auto& s : samples) {
    const double v = value(s);
    sum += v;
    sq += v * v;
  }
  const double n = static_cast<double>(samples.size());
  const double mean = sum / n;
  return {mean, std::max(0.0, sq / n - mean * mean)};
}

}  // namespace

bool StationarityDetector::still() const {
  // At least 5 samples, spanning most of the window.
  if (samples_.size() < 5 || samples_.back().t - samples_.front().t < 0.8 * window_)
    return false;
  const auto acc = meanVariance(samples_, [](const ImuSample& s) { return s.accel.norm(); });
  const auto gyro = meanVariance(samples_, [](const ImuSample& s) { return s.gyro_z; });
  return acc.second <= acc_std_ * acc_std_ && gyro.second <= gyro_std_ * gyro_std_;
}

double StationarityDetector::meanRate() const {
  if (samples_.empty()) return 0.0;
  return meanVariance(samples_, [](const ImuSample& s) { return s.gyro_z; }).first;
}

bool StationarityDetector::notTurning(double gyro_bias) const {
  return still() && std::abs(meanRate() - gyro_bias) <= rate_;
}

}  // namespace uwbloc::loc
