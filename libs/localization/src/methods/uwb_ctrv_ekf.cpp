#include "uwbloc/localization/methods/uwb_ctrv_ekf.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

UwbCtrvEkf::UwbCtrvEkf(const UwbCtrvEkfParams& params, const EstimatorContext& context)
    : FixFilter(params.fix, context), params_(params) {
  if (context.initial_pose) start_heading_ = context.initial_pose->z();
}

void UwbCtrvEkf::learn(const EstimatorStatistics& learnt) {
  FixFilter::learn(learnt);
  if (learnt.mean_square_speed) start_speed_var_ = std::max(1.0, *learnt.mean_square_speed);
}

// The first start: at rest at the fix with the start pose's heading when the run has one. At
// rest, and at every restart, the course is unobservable and the linearised CTRV model spreads
// the position only along the held course, so fixes off that line are refused again and again
// (a restart that held the start pose's heading: Plaza2 9.448 m). Until the tag is seen to move
// the state is then the position and a Cartesian velocity (trackAtRest), and the CTRV state is
// taken from that velocity once its speed stands beyond 3 sigma (startCourse).
void UwbCtrvEkf::start(const uwb::Fix& fix) {
  const bool heading_known = start_heading_ && !started_;
  x_ << fix.position, 0.0, heading_known ? *start_heading_ : x_(3), 0.0;
  p_.setZero();  // what pose() reports until the course starts
  p_.topLeftCorner<2, 2>() = fix.covariance;
  p_(2, 2) = start_speed_var_;
  p_(3, 3) = heading_known ? 0.1 : M_PI * M_PI;
  p_(4, 4) = 0.25;
  started_ = true;
  at_rest_ = true;
  kalman::initialiseFromFix(fix, cv_x_, cv_p_, std::sqrt(start_speed_var_));
}

// The course is lost when its variance has grown past a full turn or the speed is within 2 sigma
// of zero: either way the direction of motion is unknown, and only the speed's size is kept. The
// Cartesian velocity starts at zero with E|v|^2 = s^2 + P_ss on each axis, but never more than the
// start's speed spread (the learnt path's mean squared speed, at least 1 m^2/s^2); the position
// and its covariance are kept. (The CTRV state mapped through v = s (cos theta, sin theta) keeps
// the dead course instead: its velocity across that course has a variance of s^2 P_theta, near
// zero at rest, and the tag that set off across it was refused as before. Without the bound, a
// diverged track's speed let one far fix pass for motion: the paper's least-squares fixes on
// Plaza2 drove the track off at 40-700 m/s, 182 m RMSE. The start's spread alone, at rest, let
// single wrong fixes on the demo with two simulated tags set the tag off at 2 m/s: 0.082 m
// against 0.053 m.)
void UwbCtrvEkf::loseCourse() {
  ++stats_.events["course_lost"];
  cv_x_ << x_.head<2>(), 0.0, 0.0;
  cv_p_.setZero();
  cv_p_.topLeftCorner<2, 2>() = p_.topLeftCorner<2, 2>();
  cv_p_.bottomRightCorner<2, 2>() =
      std::min(x_(2) * x_(2) + p_(2, 2), start_speed_var_) * Eigen::Matrix2d::Identity();
  at_rest_ = true;
}

bool UwbCtrvEkf::trackAtRest(const uwb::Fix& fix, double dt) {
  // Constant velocity, each axis with the white acceleration of std sigma_a held over dt.
  Eigen::Matrix4d f = Eigen::Matrix4d::Identity();
  f.topRightCorner<2, 2>() = dt * Eigen::Matrix2d::Identity();
  Eigen::Matrix<double, 4, 2> g = Eigen::Matrix<double, 4, 2>::Zero();
  g.topRows<2>() = 0.5 * dt * dt * Eigen::Matrix2d::Identity();
  g.bottomRows<2>() = dt * Eigen::Matrix2d::Identity();
  cv_x_ = f * cv_x_;
  cv_p_ = f * cv_p_ * f.transpose() + params_.sigma_a * params_.sigma_a * g * g.transpose();
  Eigen::Matrix<double, 2, 4> h = Eigen::Matrix<double, 2, 4>::Zero();
  h.leftCols<2>().setIdentity();
  const auto inn = kalman::innovate<4, 2>(cv_p_, Eigen::Vector2d(fix.position - cv_x_.head<2>()), h,
                                          fix.covariance);
  const bool in_gate = kalman::inGate(inn, uwb::ChiSquareGate(params_.fix.gate));
  if (in_gate)
    kalman::josephUpdate<4, 2>(cv_x_, cv_p_, inn, h, fix.covariance);
  else
    countRejection("kf_innovation_gate");
  x_.head<2>() = cv_x_.head<2>();
  p_.topLeftCorner<2, 2>() = cv_p_.topLeftCorner<2, 2>();
  startCourse();
  return in_gate;
}

// Moved: the speed beyond 3 sigma of its estimate along the velocity. The CTRV state then takes
// s = |v| and theta = atan2(v), with the first-order covariance (along v for the speed, across
// it over |v| for the course), and no turn yet.
void UwbCtrvEkf::startCourse() {
  const Eigen::Vector2d v = cv_x_.tail<2>();
  const double speed = v.norm();
  if (!(speed > 0.0)) return;
  const Eigen::Vector2d along = v / speed, across(-along.y(), along.x());
  if (!(speed * speed > 9.0 * along.dot(cv_p_.bottomRightCorner<2, 2>() * along))) return;
  Eigen::Matrix<double, 5, 4> g = Eigen::Matrix<double, 5, 4>::Zero();
  g.topLeftCorner<2, 2>().setIdentity();
  g.block<1, 2>(2, 2) = along.transpose();
  g.block<1, 2>(3, 2) = across.transpose() / speed;
  x_ << cv_x_.head<2>(), speed, std::atan2(along.y(), along.x()), 0.0;
  p_ = g * cv_p_ * g.transpose();
  p_(4, 4) = 0.25;
  at_rest_ = false;
}

bool UwbCtrvEkf::predictAndUpdate(const uwb::Fix& fix, double dt) {
  // A course whose variance has grown past a full turn (the turn rate spinning it), or a speed
  // within 2 sigma of zero, is no course: the tag is tracked at rest again until its speed stands
  // beyond 3 sigma (the gap keeps a tag near the bounds from switching at every fix). Plaza2's
  // first 20 s at rest left the filter circling in place, refusing the moving fixes; on
  // multitag_room, where the robot turns in place and drives off across its old course, the
  // filter stood 0.6 s behind, refusing fixes, until it restarted (0.25 m). A course lost just
  // after a refused fix is a track lost with it: the filter restarts at this fix, as it would
  // after max_gated refusals (the least-squares fixes on Plaza2: 7.79 -> 6.19 m).
  if (!at_rest_ && (p_(3, 3) > M_PI * M_PI || x_(2) * x_(2) < 4.0 * p_(2, 2))) {
    loseCourse();
    if (lastFixRefused()) {
      ++stats_.resets;
      start(fix);
      return true;
    }
  }
  if (at_rest_) return trackAtRest(fix, dt);
  // §2.3 predict: x = f(x), P = F P F^T + Q (CTRV, ctrvPredict).
  Eigen::Matrix<double, 5, 5> f, q;
  x_ = ctrvPredict(x_, dt, &f, &q, params_.sigma_a, params_.sigma_yaw);
  x_(3) = wrapAngle(x_(3));
  p_ = f * p_ * f.transpose() + q;
  // §2.3 correct: the fix measures the position (H = [I 0]); the toolkit's steps (1)-(6).
  Eigen::Matrix<double, 2, 5> h = Eigen::Matrix<double, 2, 5>::Zero();
  h.leftCols<2>().setIdentity();
  const auto inn = kalman::innovate<5, 2>(p_, fix.position - x_.head<2>(), h, fix.covariance);
  if (!kalman::inGate(inn, uwb::ChiSquareGate(params_.fix.gate))) {
    countRejection("kf_innovation_gate");
    return false;
  }
  kalman::josephUpdate<5, 2>(x_, p_, inn, h, fix.covariance);
  return true;
}

// The tag's course is the robot's heading while it drives forwards. At rest the heading is not
// reported, but the lever arm still needs one: the direction of the velocity once it is above
// 0.05 m/s (on the MRPT demo, whose slow robot spends much of its run at rest by this test, the
// held course there gave 0.255 m against 0.179 m), else the held course.
PoseEstimate UwbCtrvEkf::pose(double t, const Eigen::Vector3d& tag_on_robot) {
  double heading = x_(3) + (x_(2) < 0.0 ? M_PI : 0.0);
  if (at_rest_ && cv_x_.tail<2>().norm() > 0.05) heading = std::atan2(cv_x_(3), cv_x_(2));
  PoseEstimate est =
      kalman::tagTrackPose(t, x_.head<2>(), p_.topLeftCorner<2, 2>(), tag_on_robot, heading);
  est.covariance(2, 2) = p_(3, 3);
  est.heading_valid = !at_rest_ && std::abs(x_(2)) > 0.05 && p_(3, 3) < 0.25;
  return est;
}

}  // namespace uwbloc::loc
