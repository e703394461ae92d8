#include "uwbloc/dataset/dataset.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <tuple>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"

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
  if (!ds.manifest.biases.empty() && apply_bias) {
    ds.counts["ranges_bias_corrected"] = corrected;
    if (corrected == 0)
      ds.warnings.push_back(ds.manifest.bias_csv + ": no range matches any row (anchor/tag ids)");
  }
  if (!ds.manifest.range_features.empty())
    ds.counts["ranges_with_features"] = attachRangeFeatures(ds.manifest.range_features, ds.events);

  if (!ds.manifest.ground_truth.empty())
    ds.ground_truth =
        readGroundTruth(ds.manifest.ground_truth, ds.manifest.ground_truth_format, rec.step_times);
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
  for (const auto& [reason, count] : ds.counts)
    if (reason.rfind("rejected_", 0) == 0)
      ds.warnings.push_back(ds.manifest.rawlog + ": " + std::to_string(count) +
                            " messages rejected at reading (" + reason.substr(9) + ")");
  ds.start_time = loc::eventTime(ds.events.front());
  ds.end_time = loc::eventTime(ds.events.back());
  if (auto w = referenceBeyondRecordingWarning(ds)) ds.warnings.push_back(*w);
  return ds;
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

std::optional<std::string> referenceCoverageWarning(const Dataset& ds) {
  if (ds.ground_truth.empty() || ds.events.empty()) return std::nullopt;
  const double t0 = ds.start_time, t1 = ds.end_time;
  const double g0 = ds.ground_truth.front().t, g1 = ds.ground_truth.back().t;
  const double overlap = std::max(0.0, std::min(t1, g1) - std::max(t0, g0));
  const double span = t1 - t0;
  if (span <= 0.0 || overlap >= 0.5 * span) return std::nullopt;
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "%s: the reference (%.3f..%.3f s) covers %.0f %% of the recording (%.3f..%.3f s)",
                ds.manifest.ground_truth.c_str(), g0, g1, 100.0 * overlap / span, t0, t1);
  return std::string(buf);
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
  return std::string(buf);
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
