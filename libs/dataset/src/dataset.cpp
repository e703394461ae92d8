#include "uwbloc/dataset/dataset.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <set>
#include <tuple>
#include <utility>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/odometry_check.hpp"
#include "uwbloc/dataset/range_geometry.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/tag_fit.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/multilateration.hpp"
#include "uwbloc/uwb/range_model.hpp"
#include "uwbloc/uwb/rigid_fit.hpp"

namespace uwbloc::data {

long attachRangeFeatures(const std::string& path, std::vector<loc::Event>& events) {
  // Key: (time in microseconds, anchor id, tag id or kAnyTag) -> powers. Rawlog timestamps are
  // stored with 100 ns resolution, so a microsecond key matches them exactly enough.
  constexpr int kAnyTag = -1;
  std::map<std::tuple<long long, int, int>, std::pair<double, double>> features;
  // Column of t, anchor_id, range, rx_power_dbm, fp_power_dbm, tag_id (-1: none); without a
  // header, by position.
  std::array<int, 6> col = {0, 1, 2, 3, 4, -1};
  size_t width = 0;  // the header's count of columns; 0: no header (5 or 8)
  static const std::array<const char*, 6> kNames = {
      "t", "anchor_id", "range", "rx_power_dbm", "fp_power_dbm", "tag_id"};
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    if (f.empty()) return;
    if (f[0] == "t") {
      for (size_t k = 0; k < kNames.size(); ++k) {
        const auto it = std::find(f.begin(), f.end(), kNames[k]);
        col[k] = it == f.end() ? -1 : static_cast<int>(it - f.begin());
        if (col[k] < 0 && k < 5)
          throwInputError(path, line,
                          std::string("the header has no '") + kNames[k] +
                              "' column (expected 't,anchor_id,range,rx_power_dbm,"
                              "fp_power_dbm[,true_range,error,nlos][,tag_id]')");
      }
      width = f.size();
      return;
    }
    if (width ? f.size() != width : (f.size() != 5 && f.size() != 8))
      throwInputError(path, line,
                      width ? "expected " + std::to_string(width) +
                                  " fields, as the header has, got " + std::to_string(f.size())
                            : "expected 5 fields 't,anchor_id,range,rx_power_dbm,fp_power_dbm' (8 "
                              "with 'true_range,error,nlos'), got " +
                                  std::to_string(f.size()));
    const auto field = [&](int k) { return f[static_cast<size_t>(col[static_cast<size_t>(k)])]; };
    const double t = parseNumber(field(0), path, line, "t");
    const int id = parseId(field(1), path, line, "anchor_id");
    parseNumber(field(2), path, line, "range");
    const int tag = col[5] < 0 ? kAnyTag : parseId(field(5), path, line, "tag_id");
    features[{std::llround(t * 1e6), id, tag}] = {
        parseNumber(field(3), path, line, "rx_power_dbm"),
        parseNumber(field(4), path, line, "fp_power_dbm")};
  });
  long attached = 0;
  for (auto& e : events) {
    auto* r = std::get_if<uwb::Range>(&e);
    if (!r) continue;
    // The rawlog's clock and the CSV's six decimals may differ by a microsecond's rounding.
    const long long us = std::llround(r->t * 1e6);
    auto it = features.end();
    for (const int tag : {r->tag_id, kAnyTag})
      for (const long long d : {0LL, -1LL, 1LL})
        if (it == features.end()) it = features.find({us + d, r->anchor_id, tag});
    if (it == features.end()) continue;
    r->rx_power_dbm = it->second.first;
    r->fp_power_dbm = it->second.second;
    ++attached;
  }
  return attached;
}

namespace {

// The share of the recording's span that the reference's span overlaps (1 without a reference
// or a span).
double referenceCoverage(const Dataset& ds) {
  if (ds.ground_truth.empty() || ds.events.empty()) return 1.0;
  const double span = ds.end_time - ds.start_time;
  const double overlap = std::max(0.0, std::min(ds.end_time, ds.ground_truth.back().t) -
                                           std::max(ds.start_time, ds.ground_truth.front().t));
  return span > 0.0 ? overlap / span : 1.0;
}

// "moved by S s (each departs ... by a median D m there, <otherwise>): <cause>, state it in the
// manifest: [dataset] gt_time_offset = <the manifest's offset + S>".
std::string stampsMovedBy(const Dataset& ds, double shift, double there,
                          const std::string& otherwise, const std::string& cause) {
  char buf[500];
  std::snprintf(buf, sizeof buf,
                "moved by %+.3f s (each departs from its link's median error by a median %.3f m "
                "there, %s): %s, state it in the manifest: [dataset] gt_time_offset = %.3f",
                shift, there, otherwise.c_str(), cause.c_str(), ds.manifest.gt_time_offset + shift);
  return buf;
}

}  // namespace

bool Dataset::provides(const std::string& need) const {
  if (need == "map") return map != nullptr;
  for (const auto& e : events) {
    if (need == "ranges" && std::holds_alternative<uwb::Range>(e)) return true;
    if (need == "odometry" && std::holds_alternative<loc::OdometryIncrement>(e)) return true;
    if (need == "scans" && std::holds_alternative<loc::LaserScan>(e)) return true;
    if (need == "imu" && std::holds_alternative<loc::ImuSample>(e)) return true;
  }
  return false;
}

Dataset loadDataset(const std::string& manifest_path, const std::string& data_dir,
                    bool apply_bias) {
  Dataset ds;
  ds.manifest = loadManifest(manifest_path, data_dir);
  ds.name = ds.manifest.name;
  ds.anchors = ds.manifest.anchors;
  Recording rec = readRawlog(ds.manifest.rawlog);
  ds.events = std::move(rec.events);
  ds.counts = rec.counts;
  ds.step_times = rec.step_times;
  if (ds.events.empty()) throwInputError(ds.manifest.rawlog, 0, "rawlog holds no usable events");

  long corrected = 0, robot_tags = 0;
  for (auto& e : ds.events) {
    auto* r = std::get_if<uwb::Range>(&e);
    if (!r) continue;
    if (const auto tag = ds.manifest.tags.find(r->tag_id); tag != ds.manifest.tags.end()) {
      r->on_robot = true;
      r->tag_on_robot = tag->second;
      ++robot_tags;
    }
    if (ds.manifest.tag_height) r->tag_on_robot.z() = *ds.manifest.tag_height;
    if (ds.manifest.lever_arm) r->tag_on_robot.head<2>() = *ds.manifest.lever_arm;
    if (const auto* b =
            apply_bias ? findBias(ds.manifest.biases, r->anchor_id, r->tag_id) : nullptr) {
      r->range = (r->range - b->bias) / (1.0 + b->scale);
      ++corrected;
    }
  }
  if (!ds.manifest.tags.empty()) {
    ds.counts["ranges_from_listed_tags"] = robot_tags;
    if (robot_tags == 0)
      ds.warnings.push_back(ds.manifest.path +
                            ": [tag] lists tags, but no range comes from any of them");
  }
  // Ranges from tags that are none of the robot's: every method ignores them, loudly.
  std::set<int> tags_ranging;
  bool any_on_robot = false;
  for (const auto& e : ds.events)
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      tags_ranging.insert(r->tag_id);
      any_on_robot = any_on_robot || r->on_robot;
    }
  if (!tags_ranging.empty() && !any_on_robot && ds.manifest.tags.empty()) {
    std::string list;
    for (int id : tags_ranging) list += (list.empty() ? "" : ", ") + std::to_string(id);
    ds.warnings.push_back(ds.manifest.rawlog + ": no range comes from a tag on the robot (the " +
                          "ranges' tags: " + list + "; tag 0 is the robot's unless [tag] lists " +
                          "others as tag_<id> = x y z): every method ignores them");
  }
  if (!ds.manifest.biases.empty() && apply_bias) {
    ds.counts["ranges_bias_corrected"] = corrected;
    if (corrected == 0)
      ds.warnings.push_back(ds.manifest.bias_csv + ": no range matches any row (anchor/tag ids)");
  }
  if (!ds.manifest.range_features.empty())
    ds.counts["ranges_with_features"] = attachRangeFeatures(ds.manifest.range_features, ds.events);

  if (!ds.manifest.ground_truth.empty())
    ds.ground_truth = readGroundTruth(ds.manifest.ground_truth, ds.manifest.ground_truth_format,
                                      rec.step_times, &ds.warnings);
  for (auto& p : ds.ground_truth) p.t += ds.manifest.gt_time_offset;
  if (!ds.manifest.map.empty()) {
    try {
      ds.map = std::make_shared<loc::OccupancyMap>(loc::OccupancyMap::load(ds.manifest.map));
    } catch (const std::runtime_error& e) {
      throw InputError(manifest_path + ": [dataset] map: " + e.what());
    }
  }
  if (auto w = collapsedTimeWarning(ds.events)) {
    ds.collapsed_time = true;
    ds.warnings.push_back(ds.manifest.rawlog + ": " + *w);
  }
  // A range written twice (the same stamp, anchor, tag and value: a log concatenated, a topic
  // recorded twice) is no second measurement, and a filter that takes it twice trusts it twice
  // as much (the MRPT demo with every range doubled: uwb-ekf 0.165 -> 0.769 m). Dropped,
  // counted and said; not where the stamps have collapsed, whose ranges at one stamp are
  // measurements taken apart.
  long duplicates = 0;
  std::vector<std::tuple<int, int, double>> at_stamp;  // (anchor, tag, range) at the last stamp
  double stamp = NAN;
  if (!ds.collapsed_time)
    ds.events.erase(
        std::remove_if(ds.events.begin(), ds.events.end(),
                       [&](const loc::Event& e) {
                         const auto* r = std::get_if<uwb::Range>(&e);
                         if (!r) return false;
                         if (r->t != stamp) at_stamp.clear(), stamp = r->t;
                         const std::tuple<int, int, double> key{r->anchor_id, r->tag_id, r->range};
                         if (std::find(at_stamp.begin(), at_stamp.end(), key) != at_stamp.end())
                           return ++duplicates, true;
                         at_stamp.push_back(key);
                         return false;
                       }),
        ds.events.end());
  if (duplicates > 0) ds.counts["rejected_duplicate_range"] = duplicates;
  for (const auto& [reason, count] : ds.counts)
    if (reason.rfind("rejected_", 0) == 0)
      ds.warnings.push_back(ds.manifest.rawlog + ": " + std::to_string(count) +
                            " messages rejected at reading (" + reason.substr(9) + ")");
  ds.start_time = loc::eventTime(ds.events.front());
  ds.end_time = loc::eventTime(ds.events.back());
  if (referenceCoverage(ds) < 0.5) ds.reference_shift = referenceClockShift(ds);
  if (auto w = referenceBeyondRecordingWarning(ds)) ds.warnings.push_back(*w);
  // An anchor whose ranges cannot be distances to where it is written misleads every method
  // (the MRPT demo with one anchor's x ten times too large: uwb-pf 12.2 m, graph-uwb-odom
  // 11.1 m; without that anchor 0.42 and 0.24 m): its ranges are left out, loudly.
  std::optional<int> off;
  if (auto w = rangeGeometryWarning(ds.events, ds.anchors, &off)) {
    if (off) {
      ds.anchors.erase(std::remove_if(ds.anchors.begin(), ds.anchors.end(),
                                      [&](const uwb::Anchor& a) { return a.id == *off; }),
                       ds.anchors.end());
      ds.counts["anchors_left_out"] = 1;
      *w += ". Until then its ranges are left out: every method rejects them as unknown_anchor";
    }
    ds.warnings.push_back(ds.manifest.rawlog + ": " + *w);
  }
  if (auto w = odometryTrackWarning(ds.events, ds.anchors))
    ds.warnings.push_back(ds.manifest.rawlog + ": " + *w);
  if (auto w = rangeReferenceWarning(ds)) ds.warnings.push_back(*w);
  return ds;
}

namespace {

// [m]: ranges this close to the reference need no look; beyond kUnexplained no range noise
// explains the departure (a median departure of 1.5 m is a range std of about 2.2 m).
constexpr double kLooksRight = 0.25, kUnexplained = 1.5;

// Each range's error against the reference's tag position, with the anchors' x, y moved by
// `move`.
std::vector<double> rangeErrors(const std::vector<TagFitSample>& s, const Pose2& move) {
  std::vector<double> err(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    Eigen::Vector3d a = s[i].anchor;
    a.head<2>() = transformPoint(move, a.head<2>());
    err[i] = s[i].range - (a - uwb::tagPosition(s[i].pose, s[i].tag_on_robot)).norm();
  }
  return err;
}

// How far the ranges depart from the reference, with the anchors' x, y moved by `move`: the
// median |error - its link's median error|, over all of them and per link (anchor, tag).
struct Departure {
  double overall = 0.0;
  std::map<Link, double> per_link;
};
Departure departure(const std::vector<TagFitSample>& s, const Pose2& move) {
  const auto dev = aboutLinkMedians(rangeErrors(s, move), s);
  std::map<Link, std::vector<double>> by_link;
  for (size_t i = 0; i < s.size(); ++i) by_link[{s[i].anchor_id, s[i].tag_id}].push_back(dev[i]);
  Departure d;
  for (auto& [link, e] : by_link) d.per_link[link] = loc::medianOf(std::move(e));
  d.overall = loc::medianOf(dev);
  return d;
}

// `move` (the anchors' x, y into the reference's frame) polished on the ranges themselves: the
// least overall departure, a pattern search from 0.1 m and 1 deg down to 5 mm and 0.05 deg on at
// most 2000 ranges, at most 200 moves per step whatever the data. It turns about the middle of
// the reference's path: turned about a far origin, every turn would move the path too, and the
// search would crawl along that valley.
Pose2 polishedMove(const std::vector<TagFitSample>& s, Pose2 move) {
  std::vector<TagFitSample> sub;
  Eigen::Vector2d middle = Eigen::Vector2d::Zero();
  for (size_t i = 0, step = (s.size() + 1999) / 2000; i < s.size(); i += step) {
    sub.push_back(s[i]);
    middle += s[i].pose.head<2>();
  }
  middle /= static_cast<double>(std::max<size_t>(1, sub.size()));
  const auto turned = [&](const Pose2& m, double angle) {
    const Eigen::Vector2d keep = middle - Eigen::Rotation2Dd(angle) * middle;
    return composePose(Pose2(keep.x(), keep.y(), angle), m);
  };
  double least = departure(sub, move).overall;
  for (double step = 0.1; step >= 0.005; step /= 2.0) {
    bool better = true;
    for (int moves = 0; better && moves < 200; ++moves) {
      better = false;
      for (int k = 0; k < 3; ++k)
        for (double sign : {-1.0, 1.0}) {
          Pose2 tried = move;
          if (k == 2)
            tried = turned(move, sign * step * M_PI / 18.0);
          else
            tried[k] += sign * step;
          if (const double d = departure(sub, tried).overall; d < least - 1e-9)
            least = d, move = tried, better = true;
        }
    }
  }
  // The median has corners and flat stretches where the search stops short. On precise ranges
  // (departing by kLooksRight or less there) a least squares fit follows from there (Gauss-Newton,
  // 10 steps) of the move and each link's bias, on the ranges that depart by at most three times
  // the median departure (5 cm at least); kept when it departs less. Not on noisy ranges, whose
  // noise is larger than the median's corners and whose tails least squares would follow.
  const Departure at = departure(sub, move);
  if (at.overall > kLooksRight) return move;
  std::map<Link, int> link_index;
  for (const auto& [link, d] : at.per_link)
    link_index.emplace(link, static_cast<int>(link_index.size()));
  const std::vector<double> err = rangeErrors(sub, move);
  const auto dev = aboutLinkMedians(err, sub);
  std::vector<size_t> kept;
  for (size_t i = 0; i < sub.size(); ++i)
    if (dev[i] <= std::max(3.0 * at.overall, 0.05)) kept.push_back(i);
  const int n = 3 + static_cast<int>(link_index.size());
  Pose2 fitted = move;
  // Each kept range's bias column, and each link's bias started at its kept ranges' mean error.
  std::vector<int> column(sub.size());
  Eigen::VectorXd bias = Eigen::VectorXd::Zero(n - 3), count = Eigen::VectorXd::Zero(n - 3);
  for (size_t i : kept) {
    column[i] = link_index[{sub[i].anchor_id, sub[i].tag_id}];
    bias[column[i]] += err[i], count[column[i]] += 1.0;
  }
  bias = bias.cwiseQuotient(count.cwiseMax(1.0));
  Eigen::VectorXd J = Eigen::VectorXd::Zero(n);  // of the predicted range + bias
  for (int iteration = 0; kept.size() > static_cast<size_t>(n) && iteration < 10; ++iteration) {
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(n);
    for (size_t i : kept) {
      const Eigen::Vector2d a = sub[i].anchor.head<2>(), moved_a = transformPoint(fitted, a);
      Eigen::Vector3d diff(moved_a.x(), moved_a.y(), sub[i].anchor.z());
      diff -= uwb::tagPosition(sub[i].pose, sub[i].tag_on_robot);
      const double d = diff.norm();
      if (d < 1e-6) continue;
      const int b = 3 + column[i];
      const Eigen::Vector2d u = diff.head<2>() / d;
      const Eigen::Vector2d turned_a = moved_a - fitted.head<2>();
      J[0] = u.x(), J[1] = u.y(), J[2] = u.dot(Eigen::Vector2d(-turned_a.y(), turned_a.x()));
      J[b] = 1.0;
      const double r = sub[i].range - d - bias[b - 3];
      H += J * J.transpose();
      g += J * r;
      J[b] = 0.0;
    }
    const Eigen::VectorXd step = H.ldlt().solve(g);
    if (!step.allFinite()) break;
    fitted += step.head<3>();
    bias += step.tail(n - 3);
    if (step.head<3>().norm() < 1e-7) break;
  }
  return departure(sub, fitted).overall < at.overall ? fitted : move;
}

// The rigid motion T (reference frame -> anchor frame) that takes the reference's tag positions
// onto the multilateration fixes. A fix with an NLOS range among three can sit metres off with
// no residual to show it, so first the motion most fixes agree with (within 0.5 m, from pairs of
// fixes drawn with a fixed seed), Procrustes over those; then, since an anchor's bias moves its
// fixes, the motion polished on the ranges themselves (polishedMove). Nothing with fewer than 10
// fixes or a quarter of them agreeing.
std::optional<Pose2> frameFromFixes(std::vector<TagFitSample> s) {
  std::sort(s.begin(), s.end(), [](const TagFitSample& a, const TagFitSample& b) {
    return std::tie(a.tag_id, a.t) < std::tie(b.tag_id, b.t);
  });
  std::vector<AnchorRange> ranges;
  ranges.reserve(s.size());
  for (const auto& x : s)
    ranges.push_back({x.t, x.tag_id, x.anchor_id, x.anchor, x.range, x.tag_on_robot.z()});
  std::vector<uwb::BodyPoint> pairs;
  for (const auto& [last, fix] : batchFixes(ranges))
    pairs.push_back({uwb::tagPosition(s[last].pose, s[last].tag_on_robot).head<2>(), fix,
                     Eigen::Matrix2d::Identity()});
  if (pairs.size() < 10) return std::nullopt;
  const auto inliers = [&](const Pose2& T) {
    std::vector<uwb::BodyPoint> in;
    for (const auto& p : pairs)
      if ((p.measured - transformPoint(T, p.on_body)).norm() <= 0.5) in.push_back(p);
    return in;
  };
  std::mt19937 rng(1);
  std::uniform_int_distribution<size_t> pick(0, pairs.size() - 1);
  std::vector<uwb::BodyPoint> best;
  for (int draw = 0; draw < 200; ++draw) {
    const size_t a = pick(rng), b = pick(rng);
    if ((pairs[a].on_body - pairs[b].on_body).norm() < 1.0) continue;  // no heading from them
    auto in = inliers(uwb::procrustes2d({pairs[a], pairs[b]}, {1.0, 1.0}));
    if (in.size() > best.size()) best = std::move(in);
  }
  if (best.size() < std::max<size_t>(10, pairs.size() / 4)) return std::nullopt;
  // Polished as the move of the anchors into the reference's frame, T^-1.
  const Pose2 T = uwb::procrustes2d(best, std::vector<double>(best.size(), 1.0));
  return relativePose(polishedMove(s, relativePose(T, Pose2::Zero())), Pose2::Zero());
}

// The same motion T from the ranges alone, for recordings whose ranges come one anchor at a
// time and so give no fixes. For a heading theta of T, each range says that T's translation t
// lies on a circle: |t - (anchor - R(theta) p)| = planar range, p the reference's tag position.
// At the right heading the circles of most ranges meet at one point (their radii less a bias
// common to all). So, on every heading 2 deg apart, the t that most circles pass within 1 m of
// (t and the bias from four circles drawn with a fixed seed, 100 draws, on at most 400 ranges
// evenly spread); the heading and t with the most, then polished as above. Nothing when fewer
// than a quarter of the ranges (and 30) agree.
std::optional<Pose2> frameFromRanges(const std::vector<TagFitSample>& s) {
  struct Circle {
    Eigen::Vector2d anchor, p;
    double radius;
  };
  std::vector<Circle> c;
  for (size_t i = 0, step = (s.size() + 399) / 400; i < s.size(); i += step) {
    const Eigen::Vector3d tag = uwb::tagPosition(s[i].pose, s[i].tag_on_robot);
    const double dz = s[i].anchor.z() - tag.z(), h2 = s[i].range * s[i].range - dz * dz;
    if (h2 > 0.0) c.push_back({s[i].anchor.head<2>(), tag.head<2>(), std::sqrt(h2)});
  }
  if (c.size() < 30) return std::nullopt;
  std::mt19937 rng(1);
  std::uniform_int_distribution<size_t> pick(0, c.size() - 1);
  std::vector<Eigen::Vector2d> centre(c.size());
  size_t most = 0;
  Pose2 best = Pose2::Zero();
  for (int deg = 0; deg < 360; deg += 2) {
    const double th = deg * M_PI / 180.0;
    const Eigen::Matrix2d R = Eigen::Rotation2Dd(th).toRotationMatrix();
    for (size_t i = 0; i < c.size(); ++i) centre[i] = c[i].anchor - R * c[i].p;
    for (int draw = 0; draw < 100; ++draw) {
      // |t - centre|^2 = (radius - b)^2, b a bias common to the ranges: three of these less a
      // fourth are linear in (t, b).
      const size_t m0 = pick(rng);
      Eigen::Matrix3d A;
      Eigen::Vector3d rhs;
      for (int row = 0; row < 3; ++row) {
        const size_t m = pick(rng);
        const double r0 = c[m0].radius, r = c[m].radius;
        A.row(row) << 2.0 * (centre[m] - centre[m0]).transpose(), -2.0 * (r - r0);
        rhs[row] = centre[m].squaredNorm() - centre[m0].squaredNorm() - r * r + r0 * r0;
      }
      if (std::abs(A.determinant()) < 1e-3) continue;
      const Eigen::Vector3d tb = A.partialPivLu().solve(rhs);
      if (!tb.allFinite()) continue;
      size_t agree = 0;
      for (size_t m = 0; m < c.size(); ++m)
        agree += std::abs((tb.head<2>() - centre[m]).norm() + tb.z() - c[m].radius) <= 1.0;
      if (agree > most) most = agree, best = Pose2(tb.x(), tb.y(), th);
    }
  }
  if (most < std::max<size_t>(30, c.size() / 4)) return std::nullopt;
  return relativePose(polishedMove(s, relativePose(best, Pose2::Zero())), Pose2::Zero());
}

// At most `most` finite ranges from the robot's tags, evenly spread over the recording.
std::vector<loc::Event> spreadRanges(const Dataset& ds, size_t most) {
  size_t ranges = 0;
  for (const auto& e : ds.events) ranges += std::holds_alternative<uwb::Range>(e);
  const size_t stride = std::max<size_t>(1, (ranges + most - 1) / most);
  std::vector<loc::Event> some;
  size_t k = 0;
  for (const auto& e : ds.events)
    if (const auto* r = std::get_if<uwb::Range>(&e);
        r && r->on_robot && std::isfinite(r->range) && k++ % stride == 0)
      some.push_back(e);
  return some;
}

// The overall departure of `some` with the reference's stamps moved by `lag` (interpolated
// between poses at most `max_gap` apart); HUGE_VAL with fewer than `least` of them beside it.
double departureAtLag(const Dataset& ds, const std::vector<loc::Event>& some, double lag,
                      double max_gap, size_t least) {
  const auto s = rangesBesideReference(some, ds.anchors, ds.ground_truth, lag, max_gap);
  return s.size() < least ? HUGE_VAL : departure(s, Pose2::Zero()).overall;
}

// Golden-section search of `at` between lo and hi, to 5 ms: the middle of the last bracket.
template <typename At>
double goldenSection(const At& at, double lo, double hi) {
  const double phi = (std::sqrt(5.0) - 1.0) / 2.0;
  while (hi - lo > 0.005) {
    const double a = hi - phi * (hi - lo), b = lo + phi * (hi - lo);
    if (at(a) < at(b))
      hi = b;
    else
      lo = a;
  }
  return 0.5 * (lo + hi);
}

// The lag of the reference's clock behind the ranges' that makes them agree best, within 5 s:
// the overall departure on at most 4000 ranges over a grid of lags, then golden-section search
// between the best one's neighbours, to 5 ms. With its departure, and the departure at no lag.
struct ClockLag {
  double lag = 0.0, departure = 0.0, at_zero = 0.0;
};
ClockLag clockLag(const Dataset& ds) {
  const std::vector<loc::Event> some = spreadRanges(ds, 4000);
  const auto at = [&](double lag) { return departureAtLag(ds, some, lag, 1.0, 50); };
  std::vector<double> grid = {0.0};
  for (double g : {0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 5.0})
    grid.push_back(g), grid.push_back(-g);
  std::sort(grid.begin(), grid.end());
  std::vector<double> d;
  for (double g : grid) d.push_back(at(g));
  const size_t best = static_cast<size_t>(std::min_element(d.begin(), d.end()) - d.begin());
  ClockLag c{grid[best], d[best],
             d[static_cast<size_t>(std::find(grid.begin(), grid.end(), 0.0) - grid.begin())]};
  const double mid = goldenSection(at, grid[best > 0 ? best - 1 : best],
                                   grid[best + 1 < grid.size() ? best + 1 : best]);
  if (const double dm = at(mid); dm < c.departure) c.lag = mid, c.departure = dm;
  return c;
}

// How the odometry turns beside the reference's heading: the correlation, over the odometry's
// increments, of each one's turn with the reference's change of heading over its interval (+1:
// the same way, -1: mirrored). Nothing without a reference heading, or with under 20 increments
// beside it or 0.5 rad of turning in all.
std::optional<double> odometryTurnAgreement(const Dataset& ds) {
  if (!ds.manifest.reference_heading) return std::nullopt;
  double ab = 0.0, aa = 0.0, bb = 0.0, turned = 0.0;
  long n = 0;
  std::optional<Eigen::Vector3d> at_last;  // the reference at the previous increment's time
  for (const auto& e : ds.events) {
    const auto* odo = std::get_if<loc::OdometryIncrement>(&e);
    if (!odo) continue;
    const auto end = interpolateGroundTruth(ds.ground_truth, odo->t, 1.0);
    const auto start = std::exchange(at_last, end);
    if (!start || !end || !std::isfinite(odo->delta.z())) continue;
    const double a = odo->delta.z(), b = loc::wrapAngle(end->z() - start->z());
    ab += a * b, aa += a * a, bb += b * b, turned += std::abs(a), ++n;
  }
  if (n < 20 || turned < 0.5 || !(aa > 0.0 && bb > 0.0)) return std::nullopt;
  return ab / std::sqrt(aa * bb);
}

// A robot that drives forward sees a lag of the reference's clock and a tag behind (or ahead of)
// the reference point alike. When the tag's place on the robot (fitTagOnRobot: the reference
// must carry the heading, and the ranges come from one tag) explains the ranges about as well as
// the lag, `departure` (within 1 cm), the sentence that says so; nothing otherwise.
std::string leverArmAlike(const Dataset& ds, const std::vector<TagFitSample>& s, double departure) {
  if (!ds.manifest.reference_heading) return std::string();
  for (const auto& x : s)
    if (x.tag_id != s.front().tag_id) return std::string();
  const Eigen::Vector3d given = s.front().tag_on_robot;
  const TagFit fit = fitTagOnRobot(s, given, true, false);
  if ((fit.tag - given).head<2>().norm() < 0.05 || fit.deviation > departure + 0.01)
    return std::string();
  char buf[500];
  std::snprintf(buf, sizeof buf,
                " Or the tag sits at (%.2f, %.2f) m on the robot, not at (%.2f, %.2f) m, which "
                "explains the ranges as well (a median %.3f m): along the travel a lag and a "
                "lever arm read alike, and these ranges cannot tell which it is. If that, state "
                "it: [tag] lever_arm_x = %.2f and lever_arm_y = %.2f",
                fit.tag.x(), fit.tag.y(), given.x(), given.y(), fit.deviation, fit.tag.x(),
                fit.tag.y());
  return buf;
}

}  // namespace

std::optional<std::string> rangeReferenceWarning(const Dataset& ds) {
  if (ds.ground_truth.size() < 2) return std::nullopt;
  const auto s = rangesBesideReference(ds.events, ds.anchors, ds.ground_truth);
  if (s.size() < 50) return std::nullopt;
  // The clocks: a lag of 50 ms or more that takes a fifth of the departure away, at least 2 cm
  // of it, and leaves no more than kLooksRight (a frame likewise). Not against a reference sampled
  // more than 0.5 s apart: its straight chords, and which ranges have a sample within 1 s, move
  // with the lag more than the lag shows.
  std::vector<double> steps;
  for (size_t k = 1; k < ds.ground_truth.size(); ++k)
    steps.push_back(ds.ground_truth[k].t - ds.ground_truth[k - 1].t);
  const ClockLag lag = loc::medianOf(steps) <= 0.5 ? clockLag(ds) : ClockLag{};
  const bool clocks = std::abs(lag.lag) >= 0.05 && lag.departure < 0.8 * lag.at_zero &&
                      lag.at_zero - lag.departure >= 0.02 && lag.departure <= kLooksRight;
  const Departure before = departure(s, Pose2::Zero());
  std::string bad_links;
  for (const auto& [link, d] : before.per_link)
    if (d > kUnexplained) {
      char one[80];
      std::snprintf(one, sizeof one, "%sanchor %d (tag %d) %.2f m", bad_links.empty() ? "" : ", ",
                    link.first, link.second, d);
      bad_links += one;
    }
  if (!clocks && before.overall <= kLooksRight && bad_links.empty()) return std::nullopt;
  // The rigid motion T that takes the reference (`samples`: as recorded, or mirrored) onto the
  // anchors' frame, when it explains the ranges: over 0.2 m or 2 deg, it halves the departure,
  // leaves at most kUnexplained, and leaves no link departing by more than before (give or take
  // kLooksRight; two anchors swapped can look like a half turn that mends them and breaks the
  // others).
  struct Frame {
    Pose2 T = Pose2::Zero();
    double after = HUGE_VAL;
    bool from_fixes = false, mirrored = false;
  };
  const auto frameOf = [&](const std::vector<TagFitSample>& samples,
                           bool mirrored) -> std::optional<Frame> {
    Frame f{Pose2::Zero(), HUGE_VAL, true, mirrored};
    auto T = frameFromFixes(samples);
    if (!T) f.from_fixes = false, T = frameFromRanges(samples);
    if (!T) return std::nullopt;
    // The anchors in the reference's frame: T^-1 applied to them.
    const Departure moved_by_T = departure(samples, relativePose(*T, Pose2::Zero()));
    f.T = *T;
    f.after = moved_by_T.overall;
    bool every_link = true;
    for (const auto& [link, d] : moved_by_T.per_link)
      every_link = every_link && d <= before.per_link.at(link) + kLooksRight;
    const bool moved =
        mirrored || T->head<2>().norm() > 0.2 || std::abs(T->z()) > 2.0 * M_PI / 180.0;
    if (!moved || !every_link || f.after >= 0.5 * before.overall || f.after > kUnexplained)
      return std::nullopt;
    return f;
  };
  std::optional<Frame> frame;
  if (before.overall > kLooksRight) {
    frame = frameOf(s, false);
    // A reference in a left-handed frame (a y-up motion capture's x and z, say): its y and
    // heading negated. Also tried when a rigid motion leaves more than kLooksRight, and taken
    // when it leaves under half as much: three anchors mirrored can be near a turn of
    // themselves (the MRPT demo's, 82 deg, left 0.38 m; mirrored, 0.07 m).
    if (!frame || frame->after > kLooksRight) {
      auto m = s;
      for (auto& x : m) x.pose = Pose2(x.pose.x(), -x.pose.y(), -x.pose.z());
      if (auto mirrored = frameOf(m, true);
          mirrored && (!frame || mirrored->after < 0.5 * frame->after))
        frame = mirrored;
    }
  }
  // Where both a lag and a frame would explain it, the one that explains more.
  if (frame && clocks && lag.departure < frame->after) frame.reset();
  if (clocks && !frame) {
    char as_stamped[40];
    std::snprintf(as_stamped, sizeof as_stamped, "%.3f m as stamped", lag.at_zero);
    return ds.manifest.rawlog + ": the ranges agree best with the reference's stamps " +
           stampsMovedBy(ds, lag.lag, lag.departure, as_stamped,
                         "the reference's clock is likely offset; if so") +
           "." + leverArmAlike(ds, s, lag.departure);
  }
  if (!frame && before.overall <= kUnexplained && bad_links.empty()) return std::nullopt;
  char buf[1200];
  int n = std::snprintf(buf, sizeof buf,
                        "the ranges disagree with the reference: each departs from its link's "
                        "median error by a median %.2f m (%zu ranges beside the reference). ",
                        before.overall, s.size());
  if (frame) {
    // The anchors were moved by the manifest's frame F: the reference then goes to the anchors'
    // frame by F T (T after the mirror when mirrored).
    const Pose2& T = frame->T;
    Pose2 origin = composePose(ds.manifest.gt_origin_in_anchor_frame.value_or(Pose2::Zero()), T);
    // Which of the two is left-handed: the odometry (taken right-handed, as robots report it)
    // turns against a mirrored reference, and with the reference when the anchors are mirrored.
    const auto agreement = frame->mirrored ? odometryTurnAgreement(ds) : std::nullopt;
    const bool anchors_mirrored = agreement && *agreement > 0.5;
    const bool reference_mirrored = agreement && *agreement < -0.5;
    const char* which =
        !frame->mirrored     ? ""
        : anchors_mirrored   ? ", the anchors left-handed: the odometry turns with the reference"
        : reference_mirrored ? ", the reference left-handed (a y-up motion capture's x and z, "
                               "say): the odometry turns against it"
                             : ", one of the two left-handed (a y-up motion capture's x and z, "
                               "say; the ranges cannot tell which)";
    const char* fix = !frame->mirrored   ? ""
                      : anchors_mirrored ? "write the anchors with their y negated and "
                      : reference_mirrored
                          ? "write the reference with its y and heading negated and "
                          : "and it is the reference, write it with its y and heading negated and ";
    // The anchors' y negated: the reference goes to their frame by M (F T) M, M the mirror.
    if (anchors_mirrored) origin = Pose2(origin.x(), -origin.y(), -origin.z());
    std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n),
                  "The %s fit the reference%s after one rigid motion (%.1f deg, "
                  "%.2f m), which brings it to %.2f m: the reference is likely in another frame "
                  "than the anchors%s. If so, %sstate it in the manifest: [anchors] "
                  "gt_origin_in_anchor_frame = %.3f %.3f %.2f",
                  frame->from_fixes ? "multilateration fixes" : "ranges",
                  frame->mirrored ? " mirrored (its y and heading negated)" : "",
                  T.z() * 180.0 / M_PI, T.head<2>().norm(), frame->after, which, fix, origin.x(),
                  origin.y(), origin.z() * 180.0 / M_PI);
  } else {
    std::snprintf(
        buf + n, sizeof buf - static_cast<size_t>(n),
        "No rigid motion of the reference explains it%s%s: check %s, the reference's "
        "frame, and the clocks of the ranges and the reference.",
        bad_links.empty() ? "" : "; these links depart by a median over 1.5 m: ", bad_links.c_str(),
        bad_links.empty() ? "the anchors' coordinates and ids"
                          : "those anchors' coordinates and ids");
  }
  return ds.manifest.rawlog + ": " + buf;
}

std::optional<std::string> collapsedTimeWarning(const std::vector<loc::Event>& events) {
  // Readings that share a stamp by design (the ranges of one beacon observation, several tags
  // ranging at once) differ in what they measure; a collapsed clock repeats the same reading's
  // key (kind, stamp, tag, anchor) many times over.
  if (events.size() < 50) return std::nullopt;
  std::vector<std::tuple<double, size_t, int, int>> keys;
  keys.reserve(events.size());
  for (const auto& e : events) {
    const auto* r = std::get_if<uwb::Range>(&e);
    keys.emplace_back(loc::eventTime(e), e.index(), r ? r->tag_id : 0, r ? r->anchor_id : 0);
  }
  std::sort(keys.begin(), keys.end());
  const auto distinct_keys =
      static_cast<size_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
  if (10 * distinct_keys >= events.size()) return std::nullopt;
  std::vector<double> t;
  t.reserve(distinct_keys);
  for (size_t k = 0; k < distinct_keys; ++k) t.push_back(std::get<0>(keys[k]));
  const auto distinct = static_cast<size_t>(std::unique(t.begin(), t.end()) - t.begin());
  const size_t messages = events.size();
  return "timestamps have collapsed: " + std::to_string(distinct) + " distinct stamps for " +
         std::to_string(messages) +
         " messages (written with too few digits?); results from it cannot be trusted";
}

namespace {

// The sentence that gives the shift of the reference's stamps found by referenceClockShift;
// empty without one.
std::string shiftSentence(const Dataset& ds) {
  if (!ds.reference_shift) return std::string();
  const ReferenceShift& f = *ds.reference_shift;
  char elsewhere[48];
  std::snprintf(elsewhere, sizeof elsewhere, "%.2f m at the other shifts tried", f.elsewhere);
  return ". The ranges fit the reference with its stamps " +
         stampsMovedBy(ds, f.shift, f.departure, elsewhere,
                       "if its clock counts from another origin");
}

}  // namespace

std::optional<ReferenceShift> referenceClockShift(const Dataset& ds) {
  if (ds.ground_truth.size() < 2 || ds.events.empty()) return std::nullopt;
  std::vector<double> steps;
  for (size_t k = 1; k < ds.ground_truth.size(); ++k)
    steps.push_back(ds.ground_truth[k].t - ds.ground_truth[k - 1].t);
  const double max_gap = std::max(1.0, 2.5 * loc::medianOf(steps));
  const std::vector<loc::Event> some = spreadRanges(ds, 1000);
  const size_t least = std::max<size_t>(50, some.size() / 4);
  const auto at = [&](double shift) { return departureAtLag(ds, some, shift, max_gap, least); };
  const double starts = ds.start_time - ds.ground_truth.front().t;
  const double ends = ds.end_time - ds.ground_truth.back().t;
  std::vector<std::pair<double, double>> tried;  // (shift, departure), the finite ones
  for (double centre : {starts, ends, 1800.0 * std::round(starts / 1800.0)})
    for (int k = -150; k <= 150; ++k)
      if (const double d = at(centre + 0.1 * k); d < HUGE_VAL)
        tried.emplace_back(centre + 0.1 * k, d);
  if (tried.size() < 10) return std::nullopt;
  const auto best = *std::min_element(
      tried.begin(), tried.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  std::vector<double> elsewhere;
  for (const auto& [shift, d] : tried)
    if (std::abs(shift - best.first) > 1.0) elsewhere.push_back(d);
  if (elsewhere.size() < 10) return std::nullopt;
  ReferenceShift f{best.first, best.second, loc::medianOf(elsewhere)};
  if (f.departure > kLooksRight || f.departure >= 0.5 * f.elsewhere) return std::nullopt;
  const double mid = goldenSection(at, best.first - 0.1, best.first + 0.1);
  if (const double dm = at(mid); dm < f.departure) f.shift = mid, f.departure = dm;
  return f;
}

std::optional<std::string> referenceCoverageWarning(const Dataset& ds) {
  const double coverage = referenceCoverage(ds);
  if (coverage >= 0.5) return std::nullopt;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "%s: the reference (%.3f..%.3f s) covers %.0f %% of the recording (%.3f..%.3f s)",
                ds.manifest.ground_truth.c_str(), ds.ground_truth.front().t,
                ds.ground_truth.back().t, 100.0 * coverage, ds.start_time, ds.end_time);
  return buf + shiftSentence(ds);
}

double referenceReach(const Dataset& ds, double tolerance) {
  if (ds.ground_truth.empty()) return 1.0;
  const auto inside =
      std::count_if(ds.ground_truth.begin(), ds.ground_truth.end(), [&](const TimedPose& g) {
        return g.t >= ds.start_time - tolerance && g.t <= ds.end_time + tolerance;
      });
  return static_cast<double>(inside) / static_cast<double>(ds.ground_truth.size());
}

std::optional<std::string> referenceBeyondRecordingWarning(const Dataset& ds) {
  if (ds.ground_truth.empty() || ds.events.empty()) return std::nullopt;
  const double reach = referenceReach(ds);
  if (reach >= 0.95) return std::nullopt;
  const double before = std::max(0.0, ds.start_time - ds.ground_truth.front().t);
  const double after = std::max(0.0, ds.ground_truth.back().t - ds.end_time);
  char buf[360];
  std::snprintf(buf, sizeof buf,
                "%s: the reference runs %.1f s before the recording's first measurement and "
                "%.1f s after its last; %.0f %% of its samples lie beyond them, so no method can "
                "cover more than %.2f of it",
                ds.manifest.ground_truth.c_str(), before, after, 100.0 * (1.0 - reach), reach);
  return buf + shiftSentence(ds);
}

std::string formatRangeFeatures(const std::vector<loc::Event>& events,
                                const std::vector<RangeLabel>* truth) {
  std::string out = "t,anchor_id,range,rx_power_dbm,fp_power_dbm";
  out += truth ? ",true_range,error,nlos,tag_id\n" : ",tag_id\n";
  char buf[200];
  for (size_t i = 0; i < events.size(); ++i) {
    const auto* r = std::get_if<uwb::Range>(&events[i]);
    if (!r || !r->rx_power_dbm || !r->fp_power_dbm) continue;
    std::snprintf(buf, sizeof buf, "%.6f,%d,%.6f,%.2f,%.2f", r->t, r->anchor_id, r->range,
                  *r->rx_power_dbm, *r->fp_power_dbm);
    out += buf;
    if (truth) {
      const RangeLabel& g = (*truth)[i];
      if (std::isfinite(g.true_range))
        std::snprintf(buf, sizeof buf, ",%.4f,%.4f,%d", g.true_range, r->range - g.true_range,
                      g.nlos);
      else
        std::snprintf(buf, sizeof buf, ",,,");
      out += buf;
    }
    out += "," + std::to_string(r->tag_id) + "\n";
  }
  return out;
}

}  // namespace uwbloc::data
