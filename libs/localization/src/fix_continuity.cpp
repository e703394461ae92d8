#include "uwbloc/localization/fix_continuity.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

const char* toString(Continuity c) {
  switch (c) {
    case Continuity::kAsIs:
      return "as_is";
    case Continuity::kExcluded:
      return "fix_continuity_exclusion";
    case Continuity::kUnreachable:
      return "fix_unreachable";
    case Continuity::kRestart:
      return "fix_continuity_restart";
    case Continuity::kTwoRanges:
      return "two_ranges_tracked";
  }
  return "unknown";
}

void FixContinuity::seed(double t, const Eigen::Vector2d& position) {
  if (!position.allFinite() || !std::isfinite(t)) return;
  uwb::Fix f;
  f.status = uwb::FixStatus::kOk;
  f.position = position;
  f.covariance.setZero();
  keep(t, f, Eigen::Vector2d::Zero());
}

namespace {
// The largest std of a fix's position [m].
double largestStd(const Eigen::Matrix2d& cov) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(cov, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, es.eigenvalues()(1)));
}
}  // namespace

uwb::Fix FixContinuity::candidateAt(const std::vector<uwb::PlanarRange>& ranges,
                                    const Eigen::Vector2d& p) const {
  uwb::Fix f = uwb::fixAt(ranges, p);
  if (f.ok() || ranges.size() != 2 || !p.allFinite()) return f;
  // Two circles that only touch, or miss each other: the tag near the line between their anchors,
  // known along it by the ranges. Across it, y off the line lengthens the ranges r_a and r_b by
  // y^2 / 2r each to second order, which their sum (at most D, the anchors' distance) leaves
  // within its 3 sigma: y^2 <= 3 sigma_sum 2 r_a r_b / (r_a + r_b), taken as y's 3 sigma.
  const Eigen::Vector2d d = ranges[1].anchor - ranges[0].anchor;
  const double ra = std::max(ranges[0].range, params_.floor);
  const double rb = std::max(ranges[1].range, params_.floor);
  if (!(d.norm() > 1e-6)) return f;
  const Eigen::Vector2d along = d.normalized();
  const Eigen::Vector2d across(-along.y(), along.x());
  const double var_sum = std::pow(ranges[0].sigma, 2) + std::pow(ranges[1].sigma, 2);
  const double y2 = 3.0 * std::sqrt(var_sum) * 2.0 * ra * rb / (ra + rb);
  f.covariance = 0.5 * var_sum * along * along.transpose() + y2 / 9.0 * across * across.transpose();
  f.status = uwb::FixStatus::kOk;
  return f;
}

void FixContinuity::checkEveryRange() { params_.every_range = true; }

void FixContinuity::setAccelPsd(double q) {
  if (std::isfinite(q) && q > 0.0) params_.accel_psd = q;
}

void FixContinuity::raiseMaxSpeed(double v) {
  if (std::isfinite(v)) params_.max_speed = std::max(params_.max_speed, v);
}

bool FixContinuity::reachable(double t, const uwb::Fix& fix, bool own_std,
                              const Eigen::Vector2d& offset) const {
  if (!last_) return true;
  const double dt = std::max(0.0, t - last_t_);
  const Eigen::Vector2d p = fix.position + offset;
  const double reach = params_.floor + params_.max_speed * dt +
                       3.0 * ((own_std ? largestStd(fix.covariance) : 0.0) + last_std_);
  if ((p - *last_).norm() > reach) return false;
  if (!velocity_ || dt > params_.velocity_span) return true;
  Eigen::Vector4d x;
  Eigen::Matrix4d P;
  predict(t, x, P);
  Eigen::Matrix2d S =
      P.topLeftCorner<2, 2>() + std::pow(params_.floor / 3.0, 2) * Eigen::Matrix2d::Identity();
  if (own_std && fix.covariance.allFinite()) S += fix.covariance;
  const Eigen::Vector2d nu = p - x.head<2>();
  return nu.dot(S.ldlt().solve(nu)) <= params_.gate;
}

void FixContinuity::predict(double t, Eigen::Vector4d& x, Eigen::Matrix4d& P) const {
  x = track_;
  P = track_cov_;
  kalman::predictConstantVelocity(x, P, std::max(0.0, t - last_t_), params_.accel_psd, 0.0);
}

bool FixContinuity::doubtedRangesAgree(double t, const std::vector<uwb::PlanarRange>& ranges,
                                       const Eigen::Vector2d& offset) const {
  if ((doubted_.empty() && !params_.every_range) || !velocity_ ||
      t - last_t_ > params_.velocity_span)
    return true;
  Eigen::Vector4d x;
  Eigen::Matrix4d P;
  predict(t, x, P);
  const Eigen::Vector2d tag = x.head<2>() - offset;
  for (const auto& r : ranges) {
    const bool judged = params_.every_range ||
                        std::any_of(doubted_.begin(), doubted_.end(),
                                    [&](const auto& a) { return (a - r.anchor).norm() < 1e-9; });
    const Eigen::Vector2d d = tag - r.anchor;
    if (!judged || !(d.norm() > 1e-9)) continue;
    const Eigen::Vector2d u = d.normalized();
    const double var =
        r.sigma * r.sigma + u.dot(P.topLeftCorner<2, 2>() * u) + std::pow(params_.floor / 3.0, 2);
    const double e = r.range - d.norm();
    if (e * e > 9.0 * var) return false;
  }
  return true;
}

std::optional<FixContinuity::Motion> FixContinuity::motion(double t) const {
  if (!last_ || !velocity_ || t - last_t_ > params_.velocity_span) return std::nullopt;
  Eigen::Vector4d x;
  Eigen::Matrix4d P;
  predict(t, x, P);
  if (x.tail<2>().norm() > params_.max_speed) return std::nullopt;
  return Motion{x.head<2>(), x.tail<2>(), track_cov_.bottomRightCorner<2, 2>()};
}

Eigen::Vector2d FixContinuity::predicted(double t) const {
  if (!last_) return Eigen::Vector2d::Zero();
  if (!velocity_ || t - last_t_ > params_.velocity_span) return *last_;
  Eigen::Vector4d x;
  Eigen::Matrix4d P;
  predict(t, x, P);
  return x.head<2>();
}

void FixContinuity::keep(double t, const uwb::Fix& fix, const Eigen::Vector2d& offset) {
  const Eigen::Vector2d p = fix.position + offset;
  Eigen::Matrix2d R = std::pow(params_.floor / 3.0, 2) * Eigen::Matrix2d::Identity();
  if (fix.covariance.allFinite()) R += fix.covariance;
  if (params_.track && last_ && t - last_t_ <= params_.velocity_span) {
    // The track's update with the kept fix.
    Eigen::Vector4d x;
    Eigen::Matrix4d P;
    predict(t, x, P);
    const Eigen::Matrix2d S = P.topLeftCorner<2, 2>() + R;
    const Eigen::Matrix<double, 4, 2> K = P.leftCols<2>() * S.inverse();
    track_ = x + K * (p - x.head<2>());
    track_cov_ = P - K * P.topRows<2>();
    track_cov_ = 0.5 * (track_cov_ + track_cov_.transpose()).eval();
    velocity_ = true;
  } else {
    // A new track: the fix, and any velocity up to the fastest plausible.
    track_ << p, 0.0, 0.0;
    track_cov_.setZero();
    track_cov_.topLeftCorner<2, 2>() = R;
    track_cov_.bottomRightCorner<2, 2>() =
        params_.max_speed * params_.max_speed * Eigen::Matrix2d::Identity();
    velocity_ = false;
  }
  last_t_ = last_ ? std::max(last_t_, t) : t;
  last_ = p;
  last_std_ = largestStd(fix.covariance);
  unreachable_ = 0;
}

std::optional<FixContinuity::Candidate> FixContinuity::bestReachable(
    double t, const std::vector<uwb::PlanarRange>& ranges, const Solver& solve,
    const Eigen::Vector2d& offset) const {
  // The ranges a position fits: within max(3 sigma, floor) of its distance to the anchor.
  auto fits = [&](const Eigen::Vector2d& p, size_t i) {
    const auto& r = ranges[i];
    return std::abs((p - r.anchor).norm() - r.range) <= std::max(3.0 * r.sigma, params_.floor);
  };
  std::optional<Candidate> best;
  double best_distance = 0.0;
  for (size_t a = 0; a < ranges.size(); ++a)
    for (size_t b = a + 1; b < ranges.size(); ++b)
      for (const auto& p : uwb::circleIntersections(ranges[a], ranges[b])) {
        if (!p.allFinite()) continue;
        std::vector<int> in;
        std::vector<uwb::PlanarRange> subset;
        for (size_t i = 0; i < ranges.size(); ++i)
          if (fits(p, i)) in.push_back(static_cast<int>(i)), subset.push_back(ranges[i]);
        const double distance = last_ ? (p + offset - predicted(t)).norm() : 0.0;
        if (in.size() + 1 < ranges.size() || in.size() < 2 ||
            (best && (in.size() < best->in.size() ||
                      (in.size() == best->in.size() && distance >= best_distance))))
          continue;
        // A pair's intersection as a fix from the ranges it fits.
        uwb::Fix f = candidateAt(subset, p);
        if (!f.ok() || !reachable(t, f, false, offset)) continue;
        // Three ranges or more: the method's own solver over them, when it stays reachable.
        if (subset.size() >= 3) {
          uwb::Fix solved = solve(subset);
          if (solved.ok() && reachable(t, solved, false, offset)) f = solved;
        }
        best = Candidate{f, std::move(in)};
        best_distance = distance;
      }
  return best;
}

FixContinuity::Checked FixContinuity::check(double t, const uwb::Fix& fix,
                                            const std::vector<uwb::PlanarRange>& ranges,
                                            const Solver& solve, const Eigen::Vector2d& offset) {
  Checked out;
  if (reachable(t, fix, true, offset) && doubtedRangesAgree(t, ranges, offset)) {
    keep(t, fix, offset);
    doubted_.clear();
    out.fix = fix;
    return out;
  }
  if (auto c = bestReachable(t, ranges, solve, offset)) {
    keep(t, c->fix, offset);
    out.fix = c->fix;
    out.outcome = Continuity::kExcluded;
    doubted_.clear();
    for (size_t i = 0; i < ranges.size(); ++i)
      if (std::find(c->in.begin(), c->in.end(), static_cast<int>(i)) == c->in.end()) {
        out.left_out.push_back(static_cast<int>(i));
        doubted_.push_back(ranges[i].anchor);
      }
    return out;
  }
  if (++unreachable_ >= params_.max_unreachable) {
    last_.reset();  // a restart: no velocity from the position given up
    doubted_.clear();
    keep(t, fix, offset);
    out.fix = fix;
    out.outcome = Continuity::kRestart;
    return out;
  }
  out.outcome = Continuity::kUnreachable;
  return out;
}

FixContinuity::Checked FixContinuity::checkTwo(double t,
                                               const std::vector<uwb::PlanarRange>& ranges,
                                               const Eigen::Vector2d& offset) {
  Checked out;
  out.outcome = Continuity::kUnreachable;
  if (!velocity_ || ranges.size() != 2 || t - last_t_ > params_.velocity_span) return out;
  std::optional<uwb::Fix> best;
  double best_distance = 0.0;
  for (const auto& p : uwb::circleIntersections(ranges[0], ranges[1])) {
    if (!p.allFinite()) continue;
    const double distance = (p + offset - predicted(t)).norm();
    if (best && distance >= best_distance) continue;
    uwb::Fix f = candidateAt(ranges, p);
    if (!f.ok() || !reachable(t, f, false, offset)) continue;
    best = f;
    best_distance = distance;
  }
  if (!best) return out;
  keep(t, *best, offset);
  out.fix = best;
  out.outcome = Continuity::kTwoRanges;
  return out;
}

}  // namespace uwbloc::loc
