#include "uwbloc/localization/fix_continuity.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

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

void FixContinuity::raiseMaxSpeed(double v) {
  if (std::isfinite(v)) params_.max_speed = std::max(params_.max_speed, v);
}

bool FixContinuity::reachable(double t, const uwb::Fix& fix, bool own_std,
                              const Eigen::Vector2d& offset) const {
  if (!last_) return true;
  const double reach = params_.floor + params_.max_speed * std::max(0.0, t - last_t_) +
                       3.0 * ((own_std ? largestStd(fix.covariance) : 0.0) + last_std_);
  return (fix.position + offset - *last_).norm() <= reach;
}

void FixContinuity::keep(double t, const uwb::Fix& fix, const Eigen::Vector2d& offset) {
  last_t_ = last_ ? std::max(last_t_, t) : t;
  last_ = fix.position + offset;
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
        const double distance = last_ ? (p + offset - *last_).norm() : 0.0;
        if (in.size() + 1 < ranges.size() || in.size() < 2 ||
            (best && (in.size() < best->in.size() ||
                      (in.size() == best->in.size() && distance >= best_distance))))
          continue;
        // A pair's intersection as a fix from the ranges it fits (none where the circles only
        // touch: no position across the line between their anchors).
        uwb::Fix f = uwb::fixAt(subset, p);
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
  if (reachable(t, fix, true, offset)) {
    keep(t, fix, offset);
    out.fix = fix;
    return out;
  }
  if (auto c = bestReachable(t, ranges, solve, offset)) {
    keep(t, c->fix, offset);
    out.fix = c->fix;
    out.outcome = Continuity::kExcluded;
    for (size_t i = 0; i < ranges.size(); ++i)
      if (std::find(c->in.begin(), c->in.end(), static_cast<int>(i)) == c->in.end())
        out.left_out.push_back(static_cast<int>(i));
    return out;
  }
  if (++unreachable_ >= params_.max_unreachable) {
    keep(t, fix, offset);
    out.fix = fix;
    out.outcome = Continuity::kRestart;
    return out;
  }
  out.outcome = Continuity::kUnreachable;
  return out;
}

}  // namespace uwbloc::loc
