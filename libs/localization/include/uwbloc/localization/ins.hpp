// Planar inertial navigation: the 2D strapdown mechanisation of ImuSample events (gyro z,
// accelerometer x and y in the body frame) and the stationarity detectors that let a filter
// apply zero-velocity (ZUPT) and zero-angular-rate (ZARU) updates. The H∞ cubature paper
// (adaptive-hinf-ckf-uwb-ins.txt, §1) uses both before its fusion; its detector (a generalised
// likelihood-ratio test) was lost in extraction, and the windowed-variance form here is the
// standard simple one (Skog et al., "Zero-velocity detection: an algorithm evaluation", IEEE
// TBME 57(11), 2010, the "MV"/"ARE" detectors).
//
// Mechanisation, for the state (p, v, ψ) with biases b_a (body frame) and b_g, over dt:
//   ψ' = ψ + (ω - b_g) dt
//   a  = R(ψ) (f - b_a)                    (f: the measured body-frame acceleration)
//   p' = p + v dt + a dt^2 / 2,   v' = v + a dt
// with R(ψ) taken at the interval's start (first order; at 100-200 Hz the heading moves by
// under a milliradian a step).
#pragma once

#include <Eigen/Core>
#include <deque>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::loc {

/// The navigation state of the planar strapdown: position, velocity (world frame), heading, and
/// the sensor biases.
struct InsState {
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  Eigen::Vector2d v = Eigen::Vector2d::Zero();
  double yaw = 0.0;
  double gyro_bias = 0.0;
  Eigen::Vector2d accel_bias = Eigen::Vector2d::Zero();
};

/// One mechanisation step with the sample's rates over dt (see the header). `jacobian`, when
/// given, receives d(state')/d(state) in the order [p(2) v(2) ψ b_g b_a(2)].
InsState mechanise(const InsState& s, const ImuSample& imu, double dt,
                   Eigen::Matrix<double, 8, 8>* jacobian = nullptr);

/// Windowed-variance stationarity tests over the last `window` seconds of samples:
///   still (ZUPT):       var(|f|) <= acc_std^2 and var(ω) <= gyro_std^2
///   not turning (ZARU): still, and |mean ω - gyro_bias| <= rate
/// A moving wheeled robot's accelerometer sees vibration; the variance of |f| then exceeds the
/// sensor's white noise, which is what acc_std sits above.
class StationarityDetector {
 public:
  StationarityDetector(double window, double acc_std, double gyro_std, double rate)
      : window_(window), acc_std_(acc_std), gyro_std_(gyro_std), rate_(rate) {}
  void add(const ImuSample& imu);
  /// Enough samples spanning the window, and the variance tests pass.
  bool still() const;
  /// still(), and the mean rate within `rate` of the bias: the heading is not changing.
  bool notTurning(double gyro_bias) const;
  /// The mean yaw rate over the window [rad/s].
  double meanRate() const;

 private:
  double window_, acc_std_, gyro_std_, rate_;
  std::deque<ImuSample> samples_;
};

}  // namespace uwbloc::loc
