#include "uwbloc/dataset/tag_fit.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/multilateration.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::data {

std::vector<TagFitSample> rangesBesideReference(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors,
                                                const std::vector<TimedPose>& reference, double lag,
                                                double max_gap) {
  std::vector<TagFitSample> s;
  for (size_t i = 0; i < events.size(); ++i) {
    const auto* r = std::get_if<uwb::Range>(&events[i]);
    if (!r || !r->on_robot || !std::isfinite(r->range)) continue;
    const uwb::Anchor* a = uwb::findAnchor(anchors, r->anchor_id);
    const auto pose = interpolateGroundTruth(reference, r->t - lag, max_gap);
    if (a && pose)
      s.push_back(
          {*pose, a->position, r->range, r->anchor_id, r->tag_id, r->tag_on_robot, r->t, i});
  }
  return s;
}

std::vector<std::pair<size_t, Eigen::Vector2d>> batchFixes(const std::vector<AnchorRange>& ranges) {
  std::vector<std::pair<size_t, Eigen::Vector2d>> fixes;
  for (size_t i = 0; i < ranges.size();) {
    std::map<int, const AnchorRange*> latest;  // per anchor, within 0.1 s of the first
    size_t j = i;
    for (; j < ranges.size() && ranges[j].tag_id == ranges[i].tag_id &&
           ranges[j].t - ranges[i].t <= 0.1;
         ++j)
      latest[ranges[j].anchor_id] = &ranges[j];
    std::vector<uwb::PlanarRange> planar;
    for (const auto& [id, r] : latest) {
      const double dz = r->anchor.z() - r->tag_z, h2 = r->range * r->range - dz * dz;
      if (h2 > 0.0) planar.push_back({r->anchor.head<2>(), std::sqrt(h2)});
    }
    if (planar.size() >= 3)
      if (const auto fix = uwb::solveGaussNewton(planar); fix.ok() && fix.position.allFinite())
        fixes.emplace_back(j - 1, fix.position);
    i = j;
  }
  return fixes;
}

std::vector<double> aboutLinkMedians(std::vector<double> err,
                                     const std::vector<TagFitSample>& samples,
                                     std::map<Link, double>* median) {
  std::map<Link, std::vector<double>> by_link;
  for (size_t i = 0; i < samples.size(); ++i)
    by_link[{samples[i].anchor_id, samples[i].tag_id}].push_back(err[i]);
  std::map<Link, double> med;
  for (auto& [link, e] : by_link) med[link] = loc::medianOf(std::move(e));
  for (size_t i = 0; i < samples.size(); ++i)
    err[i] = std::abs(err[i] - med[{samples[i].anchor_id, samples[i].tag_id}]);
  if (median) *median = std::move(med);
  return err;
}

std::vector<double> rangeDeviations(const std::vector<TagFitSample>& samples,
                                    const Eigen::Vector3d& tag, std::map<Link, double>* bias) {
  std::vector<double> err(samples.size());
  for (size_t i = 0; i < samples.size(); ++i)
    err[i] = samples[i].range - (uwb::tagPosition(samples[i].pose, tag) - samples[i].anchor).norm();
  return aboutLinkMedians(std::move(err), samples, bias);
}

namespace {

double medianDeviation(const std::vector<TagFitSample>& s, const Eigen::Vector3d& tag) {
  return loc::medianOf(rangeDeviations(s, tag));
}

// The best of `candidates` (the current one first, kept on a tie).
void keepBest(const std::vector<TagFitSample>& s, const std::vector<Eigen::Vector3d>& candidates,
              Eigen::Vector3d& tag, double& best) {
  for (const auto& c : candidates)
    if (const double m = medianDeviation(s, c); m < best - 1e-9) best = m, tag = c;
}

}  // namespace

TagFit fitTagOnRobot(const std::vector<TagFitSample>& samples, const Eigen::Vector3d& start,
                     bool fit_lever, bool fit_height) {
  TagFit fit;
  fit.tag = start;
  if (samples.size() >= 50) {
    std::vector<TagFitSample> sub;
    const size_t step = (samples.size() + 1999) / 2000;
    for (size_t i = 0; i < samples.size(); i += step) sub.push_back(samples[i]);
    double z_lo = samples.front().anchor.z(), z_hi = z_lo;
    for (const auto& s : samples)
      z_lo = std::min(z_lo, s.anchor.z()), z_hi = std::max(z_hi, s.anchor.z());
    z_lo -= 1.0, z_hi += 1.0;
    constexpr double kStep = 0.05;
    double best = medianDeviation(sub, fit.tag);
    // Height and lever arm in turn, twice: each moves the other's best little.
    for (int round = 0; round < 2; ++round) {
      if (fit_height) {
        std::vector<Eigen::Vector3d> c;
        // At most 400 heights (20 m of anchors' span): a typo's anchor 1e6 m up must not make
        // the search run for ever.
        for (int k = 0; k <= 400 && z_lo + kStep * k <= z_hi + 1e-9; ++k)
          c.emplace_back(fit.tag.x(), fit.tag.y(), z_lo + kStep * k);
        keepBest(sub, c, fit.tag, best);
      }
      if (fit_lever) {
        std::vector<Eigen::Vector3d> c;
        for (int ix = -20; ix <= 20; ++ix)
          for (int iy = -20; iy <= 20; ++iy)
            c.emplace_back(start.x() + kStep * ix, start.y() + kStep * iy, fit.tag.z());
        keepBest(sub, c, fit.tag, best);
      }
      if (!fit_height || !fit_lever) break;
    }
  }
  fit.deviation =
      samples.empty() ? 0.0 : loc::medianOf(rangeDeviations(samples, fit.tag, &fit.bias));
  return fit;
}

}  // namespace uwbloc::data
