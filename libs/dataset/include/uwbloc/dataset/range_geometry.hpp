// The ranges against the anchors' geometry alone, with no reference.
//
// Two ranges from one tag to two anchors, taken close together, bound the anchors' distance
// apart d (the triangle inequality): |r_i - r_j| <= d <= r_i + r_j, give or take the noise and
// what the tag moved between them. NLOS and multipath only lengthen a range, so they never make
// two ranges fall short of d; anchors in another unit than the ranges (millimetres against
// metres), an anchor written in the wrong place, or ranges that are not distances do. The
// check needs nothing but the recording, so it also guards a user's first recording that has no
// reference to compare with.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::data {

/// A unit of length: its name, its symbol and the metres in one.
struct LengthUnit {
  const char* name;
  const char* symbol;
  double metres;
};
/// The units anchors written in another than metres are tried in, and ranges.
inline const std::vector<LengthUnit> kAnchorUnits = {{"millimetres", "mm", 1e-3},
                                                     {"centimetres", "cm", 1e-2},
                                                     {"inches", "in", 0.0254},
                                                     {"feet", "ft", 0.3048}};
inline const std::vector<LengthUnit> kRangeUnits = {{"millimetres", "mm", 1e-3},
                                                    {"centimetres", "cm", 1e-2}};

/// Pairs of ranges from one tag to two known anchors, the later taken at most 0.5 s after the
/// earlier (each range paired with the latest range of every other anchor; at most about 5000
/// ranges, evenly spread, start pairs). A pair is short when r_i + r_j + tol < d and long when
/// |r_i - r_j| > d + tol, tol = 0.5 m + 3 m/s x the time between them (range noise, and a tag
/// moving at up to 3 m/s); d with every anchor coordinate times `anchor_scale`, each range times
/// `range_scale`.
struct RangePairs {
  long pairs = 0, short_pairs = 0, long_pairs = 0;
  std::map<int, std::pair<long, long>> per_anchor;  ///< anchor id -> (pairs, short pairs)
  double median_shortfall = 0.0;                    ///< d - r_i - r_j over the short pairs [m]
  double shortFraction() const { return pairs > 0 ? double(short_pairs) / double(pairs) : 0.0; }
  double longFraction() const { return pairs > 0 ? double(long_pairs) / double(pairs) : 0.0; }
  /// Both bounds hold for all but a few pairs: under 10 % short and under 10 % long (on the
  /// recordings here at most 9 % short, the MRPT demo's gross errors, and 4 % long, Plaza2's NLOS).
  bool consistent() const { return shortFraction() < 0.1 && longFraction() < 0.1; }
};
RangePairs checkRangePairs(const std::vector<loc::Event>& events,
                           const std::vector<uwb::Anchor>& anchors, double anchor_scale = 1.0,
                           double range_scale = 1.0);

/// The anchors' unit that makes the ranges consistent with them (RangePairs::consistent) when
/// the anchors as written are not: the one of kAnchorUnits that alone fits. Nothing when the
/// anchors as written fit, when fewer than 50 pairs were found, when one anchor alone is off
/// (see below), or when no unit or several fit.
std::optional<LengthUnit> anchorUnitFromRanges(const std::vector<loc::Event>& events,
                                               const std::vector<uwb::Anchor>& anchors);

/// A one-line explanation when the ranges cannot be distances to the anchors where they are
/// written, with at least 50 pairs: when 10 % of them or more are short, one anchor whose pairs
/// are over half short while under a quarter of the others' are (its coordinates or id are
/// wrong), or else over half of all pairs short (with the anchors' unit that would fit, if one
/// does); over half of them long (with the ranges' unit, millimetres or centimetres, that would
/// fit); nothing otherwise. The one anchor found off, when it is, into `anchor_off`.
std::optional<std::string> rangeGeometryWarning(const std::vector<loc::Event>& events,
                                                const std::vector<uwb::Anchor>& anchors,
                                                std::optional<int>* anchor_off = nullptr);

}  // namespace uwbloc::data
