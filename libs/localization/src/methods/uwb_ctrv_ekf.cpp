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

// The first start: at rest at the fix with the start pose's heading when the run has one. Any
// other (and every restart after max_gated refused fixes): the course is unknown, and the
// linearised CTRV model at rest spreads the position only along the held heading, so fixes off
// that line would be refused again and again. Until the fixes have moved clear of their noise the
// state then tracks the position alone (trackUntilMoved), and a straight-line fit of the latest
// fixes since the start sets the speed and course (startCourse).
void UwbCtrvEkf::start(const uwb::Fix& fix) {
  const bool heading_known = start_heading_ && !started_;
  x_ << fix.position, 0.0, heading_known ? *start_heading_ : x_(3), 0.0;
  p_.setZero();
  p_.topLeftCorner<2, 2>() = fix.covariance;
  p_(2, 2) = start_speed_var_;
  p_(3, 3) = heading_known ? 0.1 : M_PI * M_PI;
  p_(4, 4) = 0.25;
  started_ = true;
  course_pending_ = !heading_known;
  pending_.clear();
  pending_.push_back({0.0, fix.position, fix.covariance.trace() / 2.0});
}

bool UwbCtrvEkf::trackUntilMoved(const uwb::Fix& fix, double dt) {
  pending_.push_back({pending_.back().t + dt, fix.position, fix.covariance.trace() / 2.0});
  if (pending_.size() > kMaxPending) pending_.pop_front();
  if (startCourse()) return true;
  // Not yet: a random walk of the position with the start's speed spread.
  Eigen::Matrix2d pos = p_.topLeftCorner<2, 2>();
  pos += start_speed_var_ * dt * dt * Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d h = Eigen::Matrix2d::Identity();
  const auto inn =
      kalman::innovate<2, 2>(pos, Eigen::Vector2d(fix.position - x_.head<2>()), h, fix.covariance);
  const bool in_gate = kalman::inGate(inn, uwb::ChiSquareGate(params_.fix.gate));
  Eigen::Vector2d xy = x_.head<2>();
  if (in_gate)
    kalman::josephUpdate<2, 2>(xy, pos, inn, h, fix.covariance);
  else
    countRejection("kf_innovation_gate");
  x_.head<2>() = xy;
  p_.topLeftCorner<2, 2>() = pos;
  return in_gate;
}

// The fit p(t) = p_end + u (t - t_end) over the latest fixes since the start, each axis alike, with
// the noise variance the larger of the fixes' own and the fit's residual (fixes that jump between
// two solutions leave a large one). Moved: at least 3 fixes and the fitted speed |u| beyond 3
// sigma of its estimate. The state then takes p_end, |u| and u's direction, with their
// first-order covariances (along u for the speed, across it over |u| for the course).
bool UwbCtrvEkf::startCourse() {
  const size_t n = pending_.size();
  if (n < 3) return false;
  double t_mean = 0.0;
  Eigen::Vector2d p_mean = Eigen::Vector2d::Zero();
  double fix_var = 0.0;
  for (const auto& f : pending_) t_mean += f.t, p_mean += f.position, fix_var += f.variance;
  t_mean /= n, p_mean /= n, fix_var /= n;
  double stt = 0.0;
  Eigen::Vector2d stp = Eigen::Vector2d::Zero();
  for (const auto& f : pending_)
    stt += (f.t - t_mean) * (f.t - t_mean), stp += (f.t - t_mean) * (f.position - p_mean);
  if (!(stt > 0.0)) return false;
  const Eigen::Vector2d u = stp / stt;
  double rss = 0.0;
  for (const auto& f : pending_) rss += (f.position - p_mean - u * (f.t - t_mean)).squaredNorm();
  const double var = std::max(fix_var, rss / (2.0 * (n - 2)));  // per axis
  const double u_var = var / stt;
  const double speed = u.norm();
  if (!(speed > 3.0 * std::sqrt(u_var))) return false;
  const double t_end = pending_.back().t;
  const double end_var = var * (1.0 / n + (t_end - t_mean) * (t_end - t_mean) / stt);
  const Eigen::Vector2d along = u / speed;
  x_ << p_mean + u * (t_end - t_mean), speed, std::atan2(along.y(), along.x()), 0.0;
  p_.setZero();
  p_.topLeftCorner<2, 2>() = end_var * Eigen::Matrix2d::Identity();
  p_(2, 2) = u_var;
  p_(3, 3) = u_var / (speed * speed);  // below 1/9: the speed is beyond 3 sigma
  // cov(p_end, u) per axis = var (t_end - t_mean) / stt, projected on along and across.
  const double pu = var * (t_end - t_mean) / stt;
  p_.block<2, 1>(0, 2) = pu * along;
  p_.block<2, 1>(0, 3) = pu * Eigen::Vector2d(-along.y(), along.x()) / speed;
  p_.block<1, 2>(2, 0) = p_.block<2, 1>(0, 2).transpose();
  p_.block<1, 2>(3, 0) = p_.block<2, 1>(0, 3).transpose();
  p_(4, 4) = 0.25;
  course_pending_ = false;
  pending_.clear();
  return true;
}

bool UwbCtrvEkf::predictAndUpdate(const uwb::Fix& fix, double dt) {
  // A course whose variance has grown past a full turn (the tag at rest: course and turn rate
  // unobservable, the turn rate spinning it) is no course: the position alone again until the
  // fixes move (Plaza2's first 20 s at rest, after which the filter circled in place and refused
  // the moving fixes).
  if (!course_pending_ && p_(3, 3) > M_PI * M_PI) {
    ++stats_.events["course_lost"];
    x_.tail<3>().setZero();
    course_pending_ = true;
    pending_.clear();
    pending_.push_back({0.0, x_.head<2>(), p_.topLeftCorner<2, 2>().trace() / 2.0});
  }
  if (course_pending_) return trackUntilMoved(fix, dt);
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

// The tag's course is the robot's heading while it drives forwards.
PoseEstimate UwbCtrvEkf::pose(double t, const Eigen::Vector3d& tag_on_robot) {
  const double heading = x_(3) + (x_(2) < 0.0 ? M_PI : 0.0);
  PoseEstimate est =
      kalman::tagTrackPose(t, x_.head<2>(), p_.topLeftCorner<2, 2>(), tag_on_robot, heading);
  est.covariance(2, 2) = p_(3, 3);
  est.heading_valid = std::abs(x_(2)) > 0.05 && p_(3, 3) < 0.25;
  return est;
}

}  // namespace uwbloc::loc
