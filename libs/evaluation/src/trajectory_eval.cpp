#include "uwbloc/evaluation/trajectory_eval.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::eval {

double medianStep(const std::vector<data::TimedPose>& reference) {
  if (reference.size() < 2) return 0.0;
  std::vector<double> steps;
  steps.reserve(reference.size() - 1);
  for (size_t i = 1; i < reference.size(); ++i)
    steps.push_back(reference[i].t - reference[i - 1].t);
  return loc::medianOf(std::move(steps));
}

namespace {
// Against a sparse reference (median step `step`), the longest interval between two estimates
// that are interpolated at a reference stamp: max_diff, or 1.5 steps when longer. Estimates
// made at the reference's own rate but at other stamps (an estimator that reports at each
// 1.06 s odometry step, beside a reference at the scans' stamps) are then paired; a gap of
// several of the reference's steps is still no estimate.
double sparseGap(const Association& association, double step) {
  return std::max(association.max_diff, 1.5 * step);
}
}  // namespace

std::string describePairing(const std::vector<data::TimedPose>& reference,
                            const Association& association) {
  char buf[320];
  if (!association.interpolate)
    std::snprintf(buf, sizeof buf, "against the nearest reference pose, at most %g s away",
                  association.max_diff);
  else if (const double step = medianStep(reference); step > association.sparse_step)
    std::snprintf(buf, sizeof buf,
                  "at the reference's own stamps (its median step, %.2f s, exceeds %g s: each "
                  "estimate is interpolated there, between estimates at most %.3g s apart)",
                  step, association.sparse_step, sparseGap(association, step));
  else
    std::snprintf(buf, sizeof buf,
                  "against the reference interpolated at each estimate's time (between "
                  "reference poses at most %g s apart)",
                  association.max_diff);
  return buf;
}

namespace {
// The estimates interpolated at each reference stamp that two of them, at most max_diff apart,
// bracket (or that one of them lands on).
std::vector<PosePair> pairAtReferenceStamps(const std::vector<loc::PoseEstimate>& estimates,
                                            const std::vector<data::TimedPose>& reference,
                                            double max_diff) {
  std::vector<data::TimedPose> poses;
  poses.reserve(estimates.size());
  for (const auto& e : estimates) poses.push_back({e.t, e.pose});
  const auto before = [](const data::TimedPose& p, double v) { return p.t < v; };
  std::vector<PosePair> out;
  for (const auto& r : reference) {
    const auto hi = std::lower_bound(poses.begin(), poses.end(), r.t - 1e-6, before);
    auto est = data::interpolateGroundTruth(poses, r.t, max_diff);
    if (hi != poses.end() && std::abs(hi->t - r.t) <= 1e-6) est = hi->pose;
    if (!est) continue;
    const auto k = static_cast<size_t>(hi - poses.begin());
    const bool heading =
        k < estimates.size() && estimates[k].heading_valid &&
        (k == 0 || std::abs(hi->t - r.t) <= 1e-6 || estimates[k - 1].heading_valid);
    out.push_back({r.t, r.pose, *est, heading});
  }
  return out;
}
}  // namespace

std::vector<PosePair> associatePoses(const std::vector<loc::PoseEstimate>& estimates,
                                     const std::vector<data::TimedPose>& reference,
                                     const Association& association) {
  if (const double step = medianStep(reference);
      association.interpolate && step > association.sparse_step)
    return pairAtReferenceStamps(estimates, reference, sparseGap(association, step));
  std::vector<PosePair> out;
  out.reserve(estimates.size());
  for (const auto& e : estimates) {
    PosePair p{e.t, Eigen::Vector3d::Zero(), e.pose, e.heading_valid};
    if (association.interpolate) {
      // A time written with fewer digits than it was estimated at (TUM files at the
      // microsecond) still lands on its reference sample.
      auto truth = data::interpolateGroundTruth(reference, e.t, association.max_diff);
      const auto hi = std::lower_bound(reference.begin(), reference.end(), e.t - 1e-6,
                                       [](const data::TimedPose& r, double v) { return r.t < v; });
      if (hi != reference.end() && std::abs(hi->t - e.t) <= 1e-6) truth = hi->pose;
      if (!truth) continue;
      p.ref = *truth;
    } else {
      const auto hi = std::lower_bound(reference.begin(), reference.end(), e.t,
                                       [](const data::TimedPose& r, double v) { return r.t < v; });
      const data::TimedPose* best = nullptr;
      if (hi != reference.end()) best = &*hi;
      if (hi != reference.begin() && (!best || e.t - (hi - 1)->t < best->t - e.t))
        best = &*(hi - 1);
      if (!best || std::abs(best->t - e.t) > association.max_diff) continue;
      p.ref = best->pose;
    }
    out.push_back(p);
  }
  return out;
}

Alignment parseAlignment(const std::string& text) {
  if (text == "none") return Alignment::kNone;
  if (text == "se2") return Alignment::kSe2;
  if (text == "se2-origin") return Alignment::kSe2Origin;
  throw std::invalid_argument("alignment '" + text + "' is none of none, se2, se2-origin");
}

std::string toString(Alignment a) {
  switch (a) {
    case Alignment::kNone:
      return "none";
    case Alignment::kSe2:
      return "se2";
    case Alignment::kSe2Origin:
      return "se2-origin";
  }
  return "none";
}

Eigen::Vector3d alignmentTransform(const std::vector<PosePair>& pairs, Alignment a) {
  if (a == Alignment::kNone || pairs.empty()) return Eigen::Vector3d::Zero();
  if (a == Alignment::kSe2Origin) {
    const Eigen::Vector3d& r = pairs.front().ref;
    Eigen::Vector3d e = pairs.front().est;
    if (!pairs.front().heading) e.z() = r.z();  // no heading to align: translation only
    // T = r * e^-1: rotation r.z - e.z, translation r.t - R(T) e.t.
    const double th = wrapAngle(r.z() - e.z());
    const double c = std::cos(th), s = std::sin(th);
    return {r.x() - (c * e.x() - s * e.y()), r.y() - (s * e.x() + c * e.y()), th};
  }
  if (pairs.size() < 2) return Eigen::Vector3d::Zero();
  // Umeyama without scale: centre both point sets; in 2D the rotation that maximises
  // sum r_c . R e_c is atan2(sum e_c x r_c, sum e_c . r_c).
  Eigen::Vector2d me = Eigen::Vector2d::Zero(), mr = Eigen::Vector2d::Zero();
  for (const auto& p : pairs) {
    me += p.est.head<2>();
    mr += p.ref.head<2>();
  }
  me /= static_cast<double>(pairs.size());
  mr /= static_cast<double>(pairs.size());
  double dot = 0.0, cross = 0.0;
  for (const auto& p : pairs) {
    const Eigen::Vector2d e = p.est.head<2>() - me, r = p.ref.head<2>() - mr;
    dot += e.x() * r.x() + e.y() * r.y();
    cross += e.x() * r.y() - e.y() * r.x();
  }
  const double th = std::atan2(cross, dot);
  const double c = std::cos(th), s = std::sin(th);
  return {mr.x() - (c * me.x() - s * me.y()), mr.y() - (s * me.x() + c * me.y()), th};
}

std::vector<PosePair> applyAlignment(std::vector<PosePair> pairs, const Eigen::Vector3d& T) {
  const double c = std::cos(T.z()), s = std::sin(T.z());
  for (auto& p : pairs) {
    const double x = p.est.x(), y = p.est.y();
    p.est = {T.x() + c * x - s * y, T.y() + s * x + c * y, wrapAngle(p.est.z() + T.z())};
  }
  return pairs;
}

ErrorStats errorStats(const std::vector<double>& errors) {
  ErrorStats s;
  s.n = static_cast<long>(errors.size());
  if (errors.empty()) return s;
  double sum = 0.0, sq = 0.0;
  s.min = errors.front();
  s.max = errors.front();
  for (double e : errors) {
    sum += e;
    sq += e * e;
    s.min = std::min(s.min, e);
    s.max = std::max(s.max, e);
  }
  const double n = static_cast<double>(errors.size());
  s.sse = sq;
  s.mean = sum / n;
  s.rmse = std::sqrt(sq / n);
  double var = 0.0;
  for (double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);  // population std, as numpy's (evo's) default
  s.median = quantile(errors, 0.5);
  return s;
}

std::vector<ErrorSample> errorSamples(const std::vector<PosePair>& pairs) {
  std::vector<ErrorSample> out;
  out.reserve(pairs.size());
  for (const auto& p : pairs) {
    ErrorSample e;
    e.t = p.t;
    e.ex = p.est.x() - p.ref.x();
    e.ey = p.est.y() - p.ref.y();
    e.e2d = std::hypot(e.ex, e.ey);
    e.eyaw = p.heading ? wrapAngle(p.est.z() - p.ref.z()) : NAN;
    out.push_back(e);
  }
  return out;
}

std::vector<double> apeErrors(const std::vector<PosePair>& pairs) {
  std::vector<double> out;
  out.reserve(pairs.size());
  for (const auto& p : pairs) out.push_back((p.est.head<2>() - p.ref.head<2>()).norm());
  return out;
}

std::vector<double> yawErrorsDeg(const std::vector<PosePair>& pairs) {
  std::vector<double> out;
  for (const auto& p : pairs)
    if (p.heading) out.push_back(std::abs(wrapAngle(p.est.z() - p.ref.z())) * 180.0 / M_PI);
  return out;
}

RpeDelta parseRpeDelta(const std::string& text) {
  RpeDelta d;
  char* end = nullptr;
  d.value = std::strtod(text.c_str(), &end);
  std::string unit(end ? end : "");
  unit.erase(std::remove(unit.begin(), unit.end(), ' '), unit.end());
  if (end == text.c_str() || !std::isfinite(d.value) || !(d.value > 0.0) ||
      (unit != "" && unit != "m" && unit != "s"))
    throw std::invalid_argument("RPE delta '" + text +
                                "' is not a positive distance or time such as 1m or 2s");
  d.seconds = unit == "s";
  return d;
}

std::string toString(const RpeDelta& d) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g%s", d.value, d.seconds ? "s" : "m");
  return buf;
}

RpeResult relativePoseError(const std::vector<PosePair>& pairs, const RpeDelta& delta) {
  std::vector<double> trans, rot;
  // The relative motion of pose b seen from pose a: (R_a^T (p_b - p_a), theta_b - theta_a).
  auto relative = [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const double c = std::cos(a.z()), s = std::sin(a.z());
    const double dx = b.x() - a.x(), dy = b.y() - a.y();
    return Eigen::Vector3d(c * dx + s * dy, -s * dx + c * dy, wrapAngle(b.z() - a.z()));
  };
  size_t i = 0;
  double path = 0.0;
  for (size_t j = 1; j < pairs.size(); ++j) {
    path += (pairs[j].ref.head<2>() - pairs[j - 1].ref.head<2>()).norm();
    const double reached = delta.seconds ? pairs[j].t - pairs[i].t : path;
    if (reached < delta.value) continue;
    Eigen::Vector3d ei = pairs[i].est, ej = pairs[j].est;
    if (!pairs[i].heading) ei.z() = pairs[i].ref.z();
    if (!pairs[j].heading) ej.z() = pairs[j].ref.z();
    const Eigen::Vector3d q = relative(pairs[i].ref, pairs[j].ref);
    const Eigen::Vector3d p = relative(ei, ej);
    // E = q^-1 p: translation R(q)^T (p_t - q_t), rotation p_th - q_th.
    const Eigen::Vector3d e = relative(q, p);
    trans.push_back(e.head<2>().norm());
    if (pairs[i].heading && pairs[j].heading) rot.push_back(std::abs(e.z()) * 180.0 / M_PI);
    i = j;
    path = 0.0;
  }
  return {errorStats(trans), errorStats(rot)};
}

TrajectoryScore scoreTrajectory(const std::vector<PosePair>& pairs, Alignment alignment,
                                const RpeDelta& delta) {
  TrajectoryScore s;
  s.pairs = static_cast<long>(pairs.size());
  s.ape = errorStats(apeErrors(pairs));
  s.alignment = alignmentTransform(pairs, alignment);
  s.ape_aligned = errorStats(apeErrors(applyAlignment(pairs, s.alignment)));
  s.yaw_deg = errorStats(yawErrorsDeg(pairs));
  s.rpe = relativePoseError(pairs, delta);
  return s;
}

}  // namespace uwbloc::eval
