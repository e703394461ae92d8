#include "uwbloc/evaluation/metrics.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::eval {

std::vector<ErrorSample> associate(const std::vector<loc::PoseEstimate>& estimates,
                                   const std::vector<data::TimedPose>& gt, double max_gap) {
  std::vector<ErrorSample> out;
  out.reserve(estimates.size());
  for (const auto& e : estimates) {
    const auto truth = interpolateGroundTruth(gt, e.t, max_gap);
    if (!truth) continue;
    ErrorSample s;
    s.t = e.t;
    s.ex = e.pose.x() - truth->x();
    s.ey = e.pose.y() - truth->y();
    s.e2d = std::hypot(s.ex, s.ey);
    s.eyaw = e.heading_valid ? wrapAngle(e.pose.z() - truth->z()) : NAN;
    out.push_back(s);
  }
  return out;
}

double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double pos = q * static_cast<double>(values.size() - 1);
  const auto i = static_cast<size_t>(std::floor(pos));
  const size_t j = std::min(i + 1, values.size() - 1);
  return values[i] + (pos - static_cast<double>(i)) * (values[j] - values[i]);
}

Metrics computeMetrics(const std::vector<ErrorSample>& errors,
                       const std::vector<loc::PoseEstimate>& estimates,
                       const std::vector<data::TimedPose>& gt, double coverage_tolerance,
                       bool reference_heading) {
  Metrics m;
  m.steps = static_cast<long>(estimates.size());
  m.associated = static_cast<long>(errors.size());
  if (!gt.empty() && !estimates.empty()) {
    std::vector<double> times;
    times.reserve(estimates.size());
    for (const auto& e : estimates) times.push_back(e.t);
    std::sort(times.begin(), times.end());
    long covered = 0;
    for (const auto& g : gt) {
      auto it = std::lower_bound(times.begin(), times.end(), g.t);
      double best = 1e300;
      if (it != times.end()) best = *it - g.t;
      if (it != times.begin()) best = std::min(best, g.t - *(it - 1));
      if (best <= coverage_tolerance) ++covered;
    }
    m.coverage = static_cast<double>(covered) / static_cast<double>(gt.size());
  }
  if (errors.empty()) {
    // Nothing to score: the metrics are undefined, not zero (null in metrics.json).
    m.rmse_x = m.rmse_y = m.rmse_2d = m.mae_2d = m.median_2d = m.p95_2d = m.max_2d = NAN;
    m.final_2d = NAN;
    return m;
  }
  double sx = 0.0, sy = 0.0, sa = 0.0;
  std::vector<double> e2d;
  e2d.reserve(errors.size());
  for (const auto& e : errors) {
    sx += e.ex * e.ex;
    sy += e.ey * e.ey;
    sa += e.e2d;
    e2d.push_back(e.e2d);
    m.max_2d = std::max(m.max_2d, e.e2d);
  }
  const double n = static_cast<double>(errors.size());
  m.rmse_x = std::sqrt(sx / n);
  m.rmse_y = std::sqrt(sy / n);
  m.rmse_2d = std::sqrt(m.rmse_x * m.rmse_x + m.rmse_y * m.rmse_y);
  m.mae_2d = sa / n;
  m.final_2d = errors.back().e2d;
  m.median_2d = quantile(e2d, 0.5);
  m.p95_2d = quantile(e2d, 0.95);
  if (reference_heading) {
    std::vector<double> yaw;
    yaw.reserve(errors.size());
    double syaw = 0.0;
    for (const auto& e : errors) {
      if (!std::isfinite(e.eyaw)) continue;
      yaw.push_back(std::abs(e.eyaw) * 180.0 / M_PI);
      syaw += yaw.back() * yaw.back();
    }
    if (!yaw.empty()) {
      m.rmse_yaw_deg = std::sqrt(syaw / static_cast<double>(yaw.size()));
      m.median_yaw_deg = quantile(yaw, 0.5);
      m.p95_yaw_deg = quantile(yaw, 0.95);
    }
  }
  for (int i = 0; i <= 20; ++i) {
    const double q = i / 20.0;
    m.cdf.emplace_back(quantile(e2d, q), q);
  }
  return m;
}

}  // namespace uwbloc::eval
