// Motion models shared by the Kalman-family methods.
#pragma once

#include <Eigen/Core>

namespace uwbloc::loc {

/// Constant-velocity model on [x y vx vy] driven by white acceleration of spectral density q
/// [m^2/s^3]:
///   F = [I dt·I; 0 I],  Q = q [dt^3/3·I dt^2/2·I; dt^2/2·I dt·I].
/// With tau > 0 the velocity decays towards zero with correlation time tau [s] (an
/// Ornstein-Uhlenbeck velocity, as for a robot that stops):
///   F = [I  tau (1 - e^{-dt/tau}) I; 0  e^{-dt/tau} I],
/// with the same Q, which then slightly overstates the noise. Without it, a direction that the
/// ranges do not observe (e.g. across the line through two anchors) keeps drifting at the last
/// estimated velocity.
void constantVelocityModel(double dt, double q, Eigen::Matrix4d& f, Eigen::Matrix4d& qd,
                           double tau = 0.0);

/// Heading of a UWB-only track, taken from the direction of motion. The tag track alone does
/// not observe heading; this is what the lever-arm correction uses.
class HeadingFromMotion {
 public:
  explicit HeadingFromMotion(double min_speed = 0.05) : min_speed_(min_speed) {}
  /// Updates from the tag velocity; returns the current heading estimate [rad].
  double update(const Eigen::Vector2d& velocity);
  double heading() const { return heading_; }
  bool valid() const { return valid_; }
  void setHeading(double h) {
    heading_ = h;
    valid_ = true;
  }

 private:
  double min_speed_;
  double heading_ = 0.0;
  bool valid_ = false;
};

/// Robot position from the tag position, removing the lever arm rotated by `heading`.
Eigen::Vector2d robotFromTag(const Eigen::Vector2d& tag, const Eigen::Vector3d& tag_on_robot,
                             double heading);

}  // namespace uwbloc::loc
