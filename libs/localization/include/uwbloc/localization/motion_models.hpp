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
/// The constant turn rate and velocity (CTRV) model over dt for the state s = [x y v theta omega]
/// (the mobile-node paper, §2.3; its equations were lost in extraction, so the standard form of
/// Schubert, Richter and Wanielik, "Comparison and evaluation of advanced motion models for
/// vehicle tracking", FUSION 2008, is used):
///   omega != 0: x += v/omega (sin(theta + omega dt) - sin theta),
///               y += v/omega (cos theta - cos(theta + omega dt)),
///   omega == 0: x += v dt cos theta, y += v dt sin theta;
///   theta += omega dt; v and omega unchanged.
/// `f`, when given, receives the Jacobian d s' / d s. `q`, when given, the process noise of a
/// white longitudinal acceleration (std `sigma_a`) and yaw acceleration (std `sigma_yaw`) held
/// over dt: Q = G diag(sigma_a^2, sigma_yaw^2) G^T, G = [[dt^2/2 cos, 0] [dt^2/2 sin, 0] [dt, 0]
/// [0, dt^2/2] [0, dt]].
Eigen::Matrix<double, 5, 1> ctrvPredict(const Eigen::Matrix<double, 5, 1>& s, double dt,
                                        Eigen::Matrix<double, 5, 5>* f = nullptr,
                                        Eigen::Matrix<double, 5, 5>* q = nullptr,
                                        double sigma_a = 0.0, double sigma_yaw = 0.0);

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

/// The tag's position on a robot at `pose` (x, y, heading): the lever arm rotated and added.
Eigen::Vector2d tagFromRobot(const Eigen::Vector3d& pose, const Eigen::Vector3d& tag_on_robot);

/// Robot position from the tag position, removing the lever arm rotated by `heading`.
Eigen::Vector2d robotFromTag(const Eigen::Vector2d& tag, const Eigen::Vector3d& tag_on_robot,
                             double heading);

}  // namespace uwbloc::loc
