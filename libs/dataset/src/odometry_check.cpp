#include "uwbloc/dataset/odometry_check.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <utility>

#include "uwbloc/dataset/tag_fit.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"
#include "uwbloc/uwb/rigid_fit.hpp"

namespace uwbloc::data {
namespace {

struct TimedPoint {
  double t;
  Eigen::Vector2d p;
};

// The fixes of the tag on the robot that ranges most: each batch of its ranges within 0.1 s of
// the batch's first, the latest range of each anchor, three anchors or more.
std::vector<TimedPoint> rangeFixes(const std::vector<loc::Event>& events,
                                   const std::vector<uwb::Anchor>& anchors) {
  std::map<int, long> per_tag;
  for (const auto& e : events)
    if (const auto* r = std::get_if<uwb::Range>(&e); r && r->on_robot) ++per_tag[r->tag_id];
  if (per_tag.empty()) return {};
  const int tag =
      std::max_element(per_tag.begin(), per_tag.end(), [](const auto& a, const auto& b) {
        return a.second < b.second;
      })->first;
  std::vector<AnchorRange> ranges;
  for (const auto& e : events)
    if (const auto* r = std::get_if<uwb::Range>(&e);
        r && r->on_robot && r->tag_id == tag && std::isfinite(r->range) && r->range > 0.0)
      if (const uwb::Anchor* a = uwb::findAnchor(anchors, r->anchor_id))
        ranges.push_back(
            {r->t, r->tag_id, r->anchor_id, a->position, r->range, r->tag_on_robot.z()});
  std::vector<TimedPoint> fixes;
  for (const auto& [last, fix] : batchFixes(ranges)) fixes.push_back({ranges[last].t, fix});
  if (fixes.size() > 5000) {
    std::vector<TimedPoint> some;
    for (size_t k = 0, step = (fixes.size() + 4999) / 5000; k < fixes.size(); k += step)
      some.push_back(fixes[k]);
    fixes = std::move(some);
  }
  return fixes;
}

// The dead-reckoned position at `t` (linear between the poses bracketing it, at most 3 s apart).
std::optional<Eigen::Vector2d> positionAt(const std::vector<TimedPoint>& path, double t) {
  const auto hi = std::lower_bound(path.begin(), path.end(), t,
                                   [](const TimedPoint& p, double v) { return p.t < v; });
  if (hi == path.end() || hi == path.begin() || hi->t - (hi - 1)->t > 3.0) return std::nullopt;
  const auto lo = hi - 1;
  const double a = (t - lo->t) / std::max(hi->t - lo->t, 1e-9);
  return Eigen::Vector2d(lo->p + a * (hi->p - lo->p));
}

}  // namespace

const std::vector<OdometryConvention>& odometryConventions() {
  static const std::vector<OdometryConvention> conventions = {
      {"as-written", "as written", {1.0, 1.0, 1.0}},
      {"clockwise",
       "with its y and turn negated (a heading that counts clockwise, or a y axis to the right)",
       {1.0, -1.0, -1.0}},
      {"degrees", "with its turn in degrees", {1.0, 1.0, M_PI / 180.0}},
      {"mm", "with its distances in millimetres", {1e-3, 1e-3, 1.0}},
      {"cm", "with its distances in centimetres", {1e-2, 1e-2, 1.0}},
  };
  return conventions;
}

std::optional<std::vector<OdometryReading>> odometryReadings(
    const std::vector<std::vector<loc::OdometryIncrement>>& candidates,
    const std::vector<loc::Event>& events, const std::vector<uwb::Anchor>& anchors) {
  if (candidates.size() != odometryConventions().size() || candidates.front().size() < 20)
    return std::nullopt;
  const std::vector<TimedPoint> fixes = rangeFixes(events, anchors);
  if (fixes.size() < 40) return std::nullopt;
  // The windows: 30 s of fixes each.
  std::vector<std::pair<size_t, size_t>> windows;
  for (size_t i = 0; i < fixes.size();) {
    size_t j = i;
    while (j < fixes.size() && fixes[j].t - fixes[i].t < 30.0) ++j;
    windows.emplace_back(i, j);
    i = j;
  }
  std::vector<OdometryReading> out;
  for (size_t c = 0; c < candidates.size(); ++c) {
    std::vector<TimedPoint> path;
    Pose2 pose = Pose2::Zero();
    for (const auto& o : candidates[c]) {
      if (!o.delta.allFinite()) continue;
      pose = composePose(pose, o.delta);
      path.push_back({o.t, pose.head<2>()});
    }
    std::vector<double> per_window;
    for (const auto& [begin, end] : windows) {
      std::vector<uwb::BodyPoint> points;
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (size_t k = begin; k < end; ++k)
        if (const auto p = positionAt(path, fixes[k].t)) {
          points.push_back({*p, fixes[k].p, Eigen::Matrix2d::Identity()});
          mean += fixes[k].p;
        }
      if (points.size() < 10) continue;
      mean /= static_cast<double>(points.size());
      double spread = 0.0;
      for (const auto& b : points) spread = std::max(spread, (b.measured - mean).norm());
      if (spread < 1.0) continue;
      // Fixes with an NLOS range sit metres off: the fit is trimmed twice, to the nearer half of
      // the points and then to those within three times their median distance (0.3 m at least).
      std::vector<double> weights(points.size(), 1.0), d(points.size());
      Pose2 T = Pose2::Zero();
      for (int round = 0; round < 3; ++round) {
        T = uwb::procrustes2d(points, weights);
        for (size_t k = 0; k < points.size(); ++k)
          d[k] = (points[k].measured - transformPoint(T, points[k].on_body)).norm();
        const double median = loc::medianOf(d);
        const double keep = round == 0 ? median : std::max(3.0 * median, 0.3);
        for (size_t k = 0; k < points.size(); ++k) weights[k] = d[k] <= keep ? 1.0 : 1e-9;
      }
      per_window.push_back(loc::medianOf(std::move(d)));
    }
    if (per_window.size() < 4) return std::nullopt;
    out.push_back({&odometryConventions()[c], std::move(per_window)});
  }
  return out;
}

std::optional<std::vector<OdometryReading>> odometryReadings(
    const std::vector<loc::Event>& events, const std::vector<uwb::Anchor>& anchors) {
  std::vector<std::vector<loc::OdometryIncrement>> candidates(odometryConventions().size());
  for (const auto& e : events)
    if (const auto* o = std::get_if<loc::OdometryIncrement>(&e))
      for (size_t c = 0; c < candidates.size(); ++c)
        candidates[c].push_back({o->t, o->delta.cwiseProduct(odometryConventions()[c].scale)});
  return odometryReadings(candidates, events, anchors);
}

std::optional<BetterReading> betterOdometryReading(const std::vector<OdometryReading>& readings) {
  const std::vector<double>& written = readings.front().per_window;
  std::optional<BetterReading> best;
  for (size_t k = 1; k < readings.size(); ++k) {
    const auto& d = readings[k].per_window;
    int wins = 0, losses = 0;
    for (size_t w = 0; w < d.size(); ++w) {
      wins += d[w] < 0.5 * written[w] && written[w] - d[w] >= 0.1;
      losses += written[w] < 0.5 * d[w] && d[w] - written[w] >= 0.1;
    }
    if (wins > (best ? best->wins : 0))
      best = BetterReading{readings[k],           wins, losses, written.size(), loc::medianOf(d),
                           loc::medianOf(written)};
  }
  if (!best || best->wins < 4 || best->wins < 3 * best->losses) return std::nullopt;
  return best;
}

std::string BetterReading::describe() const {
  char buf[600];
  std::snprintf(buf, sizeof buf,
                "the odometry does not follow the track of the ranges' own fixes as written, but "
                "does %s: in %d of %zu windows of 30 s, each laid on the fixes by its best rigid "
                "motion, it lies under half as far from them that way (a median %.2f m against "
                "%.2f m as written), and in %d farther",
                reading.convention->name, wins, windows, median, median_written, losses);
  return buf;
}

std::optional<std::string> odometryTrackWarning(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors) {
  const auto readings = odometryReadings(events, anchors);
  const auto better = readings ? betterOdometryReading(*readings) : std::nullopt;
  if (!better) return std::nullopt;
  return better->describe() +
         ". Every method that fuses it will end worse than the ranges alone until it is written "
         "that way (import csv reads it so by itself: --odometry-convention)";
}

}  // namespace uwbloc::data
