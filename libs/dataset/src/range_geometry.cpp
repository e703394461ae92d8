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

// The recording's finite, positive ranges in time order, gathered once for every check below.
std::vector<Sample> rangesInTimeOrder(const std::vector<loc::Event>& events) {
  std::vector<Sample> s;
  for (const auto& e : events)
    if (const auto* r = std::get_if<uwb::Range>(&e);
        r && std::isfinite(r->t) && std::isfinite(r->range) && r->range > 0.0)
      s.push_back({r->t, r->range, r->tag_id, r->anchor_id});
  std::stable_sort(s.begin(), s.end(), [](const Sample& a, const Sample& b) { return a.t < b.t; });
  return s;
}

// checkRangePairs on gathered ranges.
RangePairs pairsOf(const std::vector<Sample>& all, const std::vector<uwb::Anchor>& anchors,
                   double anchor_scale, double range_scale) {
  std::map<int, Eigen::Vector3d> at;
  for (const auto& a : anchors) at.emplace(a.id, anchor_scale * a.position);
  std::vector<const Sample*> s;
  for (const auto& x : all)
    if (at.count(x.anchor)) s.push_back(&x);
  const size_t stride = std::max<size_t>(1, (s.size() + kStartRanges - 1) / kStartRanges);
  // The latest range of each (tag, anchor).
  std::map<std::pair<int, int>, const Sample*> latest;
  RangePairs out;
  std::vector<double> shortfall;
  for (size_t k = 0; k < s.size(); ++k) {
    const Sample& b = *s[k];
    if (k % stride == 0) {
      for (auto it = latest.lower_bound({b.tag, std::numeric_limits<int>::min()});
           it != latest.end() && it->first.first == b.tag; ++it) {
        const Sample& a = *it->second;
        if (a.anchor == b.anchor || b.t - a.t > kWindow) continue;
        const double d = (at.at(a.anchor) - at.at(b.anchor)).norm();
        const double ra = range_scale * a.range, rb = range_scale * b.range;
        const double tol = kTolerance + kTagSpeed * (b.t - a.t);
        const bool is_short = ra + rb + tol < d;
        ++out.pairs;
        out.short_pairs += is_short;
        out.long_pairs += std::abs(ra - rb) > d + tol;
        for (int id : {a.anchor, b.anchor}) {
          auto& [n, n_short] = out.per_anchor[id];
          ++n;
          n_short += is_short;
        }
        if (is_short) shortfall.push_back(d - ra - rb);
      }
    }
    latest[{b.tag, b.anchor}] = &b;
  }
  if (!shortfall.empty()) out.median_shortfall = loc::medianOf(std::move(shortfall));
  return out;
}

// The one anchor written in the wrong place, when there is one: over half of its pairs in `p`
// short, and under a quarter of the pairs without it. (Gross short readings of one anchor, as
// the MRPT demo's beacon 1 gives, leave most of its pairs whole, and break some of the others'
// with it.)
std::optional<int> oneAnchorOff(const std::vector<Sample>& s,
                                const std::vector<uwb::Anchor>& anchors, const RangePairs& p) {
  std::optional<int> off;
  for (const auto& a : anchors) {
    const auto n = p.per_anchor.find(a.id);
    if (n == p.per_anchor.end() || 2 * n->second.second <= n->second.first) continue;
    std::vector<uwb::Anchor> others;
    for (const auto& b : anchors)
      if (b.id != a.id) others.push_back(b);
    const RangePairs q = pairsOf(s, others, 1.0, 1.0);
    if (q.pairs < 50 || q.shortFraction() >= 0.25) continue;
    if (off) return std::nullopt;  // two would do: neither is the one
    off = a.id;
  }
  return off;
}

// The one of `units` that, applied to the anchors (or to the ranges, `on_ranges`), makes the
// pairs consistent; nothing when none or several do.
std::optional<LengthUnit> onlyUnitThatFits(const std::vector<Sample>& s,
                                           const std::vector<uwb::Anchor>& anchors,
                                           const std::vector<LengthUnit>& units, bool on_ranges) {
  std::optional<LengthUnit> fit;
  for (const auto& u : units)
    if (pairsOf(s, anchors, on_ranges ? 1.0 : u.metres, on_ranges ? u.metres : 1.0).consistent()) {
      if (fit) return std::nullopt;  // two units fit: the ranges cannot tell
      fit = u;
    }
  return fit;
}

// The warning's clause naming the one unit of the anchors (or of the ranges, `on_ranges`) that
// would fit, or "".
std::string unitHint(const std::vector<Sample>& s, const std::vector<uwb::Anchor>& anchors,
                     bool on_ranges) {
  const auto fit = onlyUnitThatFits(s, anchors, on_ranges ? kRangeUnits : kAnchorUnits, on_ranges);
  if (!fit) return std::string();
  return std::string("; read in ") + fit->name + ", the " + (on_ranges ? "ranges" : "anchors") +
         " would fit them";
}

}  // namespace

RangePairs checkRangePairs(const std::vector<loc::Event>& events,
                           const std::vector<uwb::Anchor>& anchors, double anchor_scale,
                           double range_scale) {
  return pairsOf(rangesInTimeOrder(events), anchors, anchor_scale, range_scale);
}

std::optional<LengthUnit> anchorUnitFromRanges(const std::vector<loc::Event>& events,
                                               const std::vector<uwb::Anchor>& anchors) {
  const auto s = rangesInTimeOrder(events);
  const RangePairs as_written = pairsOf(s, anchors, 1.0, 1.0);
  if (as_written.pairs < 50 || as_written.consistent()) return std::nullopt;
  // One anchor off is a wrong coordinate, not a unit (read in feet, a typo of 10 times can
  // fit).
  if (oneAnchorOff(s, anchors, as_written)) return std::nullopt;
  return onlyUnitThatFits(s, anchors, kAnchorUnits, false);
}

std::optional<std::string> rangeGeometryWarning(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors,
                                                std::optional<int>* anchor_off) {
  const auto s = rangesInTimeOrder(events);
  const RangePairs p = pairsOf(s, anchors, 1.0, 1.0);
  if (p.pairs < 50) return std::nullopt;
  char buf[600];
  if (p.shortFraction() >= 0.1) {
    if (const auto off = oneAnchorOff(s, anchors, p)) {
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
      // Inconsistent, and no one anchor off: anchorUnitFromRanges's conditions hold.
      const std::string unit = unitHint(s, anchors, false);
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
  const std::string unit = unitHint(s, anchors, true);
  std::snprintf(buf, sizeof buf,
                "the ranges cannot be distances to the anchors as written: in %ld of %ld pairs of "
                "ranges from one tag to two anchors within %.1f s, the two ranges differ by more "
                "than the anchors' distance apart, which no tag position gives and NLOS only now "
                "and then%s. Check the ranges' unit and the anchors' coordinates",
                p.long_pairs, p.pairs, kWindow, unit.c_str());
  return std::string(buf);
}

}  // namespace uwbloc::data
