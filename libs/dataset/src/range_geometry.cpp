#include "uwbloc/dataset/range_geometry.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <variant>

#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::data {

namespace {

constexpr double kWindow = 0.5;     // [s] the most apart two ranges of a pair are taken
constexpr double kTolerance = 0.5;  // [m] range noise allowed for the pair
constexpr double kTagSpeed = 3.0;   // [m/s] the fastest the tag is taken to move
constexpr long kStartRanges = 5000;

struct Sample {
  double t, range;
  int tag, anchor;
};

// The one anchor written in the wrong place, when there is one: over half of its pairs in `p`
// short, and under a quarter of the pairs without it. (Gross short readings of one anchor, as
// the MRPT demo's beacon 1 gives, leave most of its pairs whole, and break some of the others'
// with it.)
std::optional<int> oneAnchorOff(const std::vector<loc::Event>& events,
                                const std::vector<uwb::Anchor>& anchors, const RangePairs& p) {
  std::optional<int> off;
  for (const auto& a : anchors) {
    const auto n = p.per_anchor.find(a.id);
    if (n == p.per_anchor.end() || 2 * n->second.second <= n->second.first) continue;
    std::vector<uwb::Anchor> others;
    for (const auto& b : anchors)
      if (b.id != a.id) others.push_back(b);
    const RangePairs q = checkRangePairs(events, others);
    if (q.pairs < 50 || q.shortFraction() >= 0.25) continue;
    if (off) return std::nullopt;  // two would do: neither is the one
    off = a.id;
  }
  return off;
}

}  // namespace

RangePairs checkRangePairs(const std::vector<loc::Event>& events,
                           const std::vector<uwb::Anchor>& anchors, double anchor_scale,
                           double range_scale) {
  std::vector<Sample> s;
  for (const auto& e : events)
    if (const auto* r = std::get_if<uwb::Range>(&e); r && std::isfinite(r->t) &&
                                                     std::isfinite(r->range) && r->range > 0.0 &&
                                                     uwb::findAnchor(anchors, r->anchor_id))
      s.push_back({r->t, range_scale * r->range, r->tag_id, r->anchor_id});
  std::stable_sort(s.begin(), s.end(), [](const Sample& a, const Sample& b) { return a.t < b.t; });
  const size_t stride = std::max<size_t>(1, (s.size() + kStartRanges - 1) / kStartRanges);
  // The latest range of each (tag, anchor).
  std::map<std::pair<int, int>, const Sample*> latest;
  RangePairs out;
  std::vector<double> shortfall;
  for (size_t k = 0; k < s.size(); ++k) {
    const Sample& b = s[k];
    if (k % stride == 0) {
      const Eigen::Vector3d pb = anchor_scale * uwb::findAnchor(anchors, b.anchor)->position;
      for (auto it = latest.lower_bound({b.tag, std::numeric_limits<int>::min()});
           it != latest.end() && it->first.first == b.tag; ++it) {
        const Sample& a = *it->second;
        if (a.anchor == b.anchor || b.t - a.t > kWindow) continue;
        const double d = (anchor_scale * uwb::findAnchor(anchors, a.anchor)->position - pb).norm();
        const double tol = kTolerance + kTagSpeed * (b.t - a.t);
        const bool is_short = a.range + b.range + tol < d;
        ++out.pairs;
        out.short_pairs += is_short;
        out.long_pairs += std::abs(a.range - b.range) > d + tol;
        for (int id : {a.anchor, b.anchor}) {
          auto& [n, n_short] = out.per_anchor[id];
          ++n;
          n_short += is_short;
        }
        if (is_short) shortfall.push_back(d - a.range - b.range);
      }
    }
    latest[{b.tag, b.anchor}] = &b;
  }
  if (!shortfall.empty()) out.median_shortfall = loc::medianOf(std::move(shortfall));
  return out;
}

std::optional<std::pair<std::string, double>> anchorUnitFromRanges(
    const std::vector<loc::Event>& events, const std::vector<uwb::Anchor>& anchors) {
  const RangePairs as_written = checkRangePairs(events, anchors);
  if (as_written.pairs < 50 || as_written.consistent()) return std::nullopt;
  // One anchor off is a wrong coordinate, not a unit (read in feet, a typo of 10 times can
  // fit).
  if (oneAnchorOff(events, anchors, as_written)) return std::nullopt;
  std::optional<std::pair<std::string, double>> fit;
  for (const auto& [name, scale] : {std::pair<const char*, double>{"millimetres", 1e-3},
                                    {"centimetres", 1e-2},
                                    {"inches", 0.0254},
                                    {"feet", 0.3048}})
    if (checkRangePairs(events, anchors, scale).consistent()) {
      if (fit) return std::nullopt;  // two units fit: the ranges cannot tell
      fit.emplace(name, scale);
    }
  return fit;
}

std::optional<std::string> rangeGeometryWarning(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors,
                                                std::optional<int>* anchor_off) {
  const RangePairs p = checkRangePairs(events, anchors);
  if (p.pairs < 50) return std::nullopt;
  char buf[600];
  if (p.shortFraction() >= 0.1) {
    if (const auto off = oneAnchorOff(events, anchors, p)) {
      if (anchor_off) *anchor_off = off;
      const auto& [n, n_short] = p.per_anchor.at(*off);
      std::snprintf(buf, sizeof buf,
                    "the ranges of anchor %d cannot be distances to where it is written: in %ld "
                    "of its %ld pairs with another anchor's range from the same tag within %.1f "
                    "s, the two ranges together fall short of the two anchors' distance apart, "
                    "which no tag position and no NLOS (it lengthens a range) can give, while the "
                    "other anchors' pairs mostly hold. Check anchor %d's coordinates and id",
                    *off, n_short, n, kWindow, *off);
      return std::string(buf);
    }
    if (p.shortFraction() > 0.5) {
      std::string unit;
      if (const auto fit = anchorUnitFromRanges(events, anchors))
        unit = "; read in " + fit->first + ", the anchors would fit them";
      std::snprintf(buf, sizeof buf,
                    "the ranges cannot be distances to the anchors as written: in %ld of %ld "
                    "pairs of ranges from one tag to two anchors within %.1f s, the two ranges "
                    "together fall short of the anchors' distance apart (by a median %.2f m), "
                    "which no tag position and no NLOS (it lengthens a range) can give%s. Check "
                    "the anchors' coordinates and their unit against the ranges'",
                    p.short_pairs, p.pairs, kWindow, p.median_shortfall, unit.c_str());
      return std::string(buf);
    }
  }
  // Ranges far too long for the anchors: NLOS lengthens one range of a pair now and then (at
  // most 4 % of the pairs on the recordings here), not most of them.
  if (p.longFraction() <= 0.5) return std::nullopt;
  std::vector<const char*> fits;
  for (const auto& [name, range_scale] :
       {std::pair<const char*, double>{"millimetres", 1e-3}, {"centimetres", 1e-2}})
    if (checkRangePairs(events, anchors, 1.0, range_scale).consistent()) fits.push_back(name);
  const std::string unit =
      fits.size() == 1 ? std::string("; read in ") + fits.front() + ", the ranges would fit them"
                       : std::string();
  std::snprintf(buf, sizeof buf,
                "the ranges cannot be distances to the anchors as written: in %ld of %ld pairs of "
                "ranges from one tag to two anchors within %.1f s, the two ranges differ by more "
                "than the anchors' distance apart, which no tag position gives and NLOS only now "
                "and then%s. Check the ranges' unit and the anchors' coordinates",
                p.long_pairs, p.pairs, kWindow, unit.c_str());
  return std::string(buf);
}

}  // namespace uwbloc::data
