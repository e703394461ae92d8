#include "uwbloc/dataset/simulator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <sstream>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

using Rng = std::mt19937_64;

bool inAny(const std::vector<Interval>& intervals, double t) {
  return std::any_of(intervals.begin(), intervals.end(),
                     [t](const Interval& i) { return t >= i.first && t <= i.second; });
}

// Ranging model of one tag-anchor measurement: LOS noise, NLOS bias, outliers, zeros, features.
class RangeModel {
 public:
  RangeModel(const UwbSimSpec& spec, const loc::OccupancyMap* map, Rng& rng)
      : spec_(spec), map_(map), rng_(rng) {}

  // Returns false when out of range (no measurement).
  bool measure(double t, int tag_id, const Eigen::Vector3d& tag, const uwb::Anchor& anchor,
               const Eigen::Vector3d& tag_on_robot, std::vector<loc::Event>& out,
               std::vector<RangeTruth>* truth) {
    const double d = (tag - anchor.position).norm();
    if (d > spec_.max_range) return false;
    std::normal_distribution<double> n01(0.0, 1.0);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    // Draw every random number every time, so that one option does not shift the others' draws.
    const double g = n01(rng_), u_nlos = u01(rng_), u_out = u01(rng_), u_mag = u01(rng_),
                 u_sign = u01(rng_), u_zero = u01(rng_), g_rx = n01(rng_), u_feat = u01(rng_),
                 g_fp = n01(rng_);
    const bool nlos = map_ && map_->segmentBlocked(tag.head<2>(), anchor.position.head<2>(),
                                                   1.5 * map_->resolution());
    double err = spec_.bias + (spec_.sigma + spec_.sigma_per_m * d) * g;
    if (auto it = spec_.anchor_bias.find(anchor.id); it != spec_.anchor_bias.end())
      err += it->second;
    if (nlos) {
      if (spec_.nlos_distribution == "exponential")
        err += -spec_.nlos_mean * std::log(std::max(1.0 - u_nlos, 1e-12));
      else if (spec_.nlos_distribution == "uniform")
        err += 2.0 * spec_.nlos_mean * u_nlos;
      else
        err += spec_.nlos_mean;
    }
    if (u_out < spec_.outlier_prob)
      err += (u_sign < 0.5 ? -1.0 : 1.0) * (1.0 + (spec_.outlier_max - 1.0) * u_mag);
    double measured = std::max(0.0, d + err);
    if (u_zero < spec_.zero_prob) measured = 0.0;

    uwb::Range r;
    r.t = t;
    r.anchor_id = anchor.id;
    r.tag_id = tag_id;
    r.on_robot = tag_id == 0;
    r.range = measured;
    r.tag_on_robot = tag_on_robot;
    if (spec_.features) {
      // Received power falls with log-distance; under NLOS the first path is attenuated more
      // than the total, so rx - fp grows (as in DW1000 data).
      const double rx =
          -60.0 - 20.0 * std::log10(std::max(d, 0.1)) + g_rx - (nlos ? 3.0 + 5.0 * u_feat : 0.0);
      const double gap = nlos ? 6.0 + 10.0 * u_feat + std::abs(g_fp) : 1.5 + 0.7 * std::abs(g_fp);
      r.rx_power_dbm = std::round(rx * 100.0) / 100.0;
      r.fp_power_dbm = std::round((rx - gap) * 100.0) / 100.0;
    }
    out.emplace_back(r);
    if (truth) truth->push_back({t, tag_id, anchor.id, d, measured - d, nlos});
    return true;
  }

 private:
  const UwbSimSpec& spec_;
  const loc::OccupancyMap* map_;
  Rng& rng_;
};

// One row per simulated range: its truth, error and NLOS flag.
std::string formatRangeTruth(const std::vector<RangeTruth>& truth) {
  std::string out = "t,tag_id,anchor_id,true_range,error,nlos\n";
  char buf[160];
  for (const auto& r : truth) {
    std::snprintf(buf, sizeof buf, "%.6f,%d,%d,%.6f,%.6f,%d\n", r.t, r.tag_id, r.anchor_id,
                  r.true_range, r.error, r.nlos ? 1 : 0);
    out += buf;
  }
  return out;
}

}  // namespace

std::string formatTimeXyPhi(const std::vector<TimedPose>& poses) {
  std::string out;
  char buf[160];
  for (const auto& p : poses) {
    std::snprintf(buf, sizeof buf, "%.6f %.6f %.6f %.9f\n", p.t, p.pose.x(), p.pose.y(),
                  p.pose.z());
    out += buf;
  }
  return out;
}

namespace {

// One slot of a ranging round: when, after the round's start, the robot's tags in it range to
// one anchor.
struct RangeSlot {
  double offset;                                      ///< [s]
  std::vector<std::pair<int, Eigen::Vector3d>> tags;  ///< id, position on the robot
};

// The slots in which the robot's tags range to anchor i of n at `rate`: one for every tag
// together, or with tags_in_turn one per tag (tag 0, then the others by id), each in its own
// share of the round. The anchors are staggered within a slot's span unless synchronous.
// `tag0`: tag 0 is simulated (augment leaves a recording's own tag alone; its slot stays).
std::vector<RangeSlot> rangeSlots(const UwbSimSpec& uwb, size_t i, size_t n, double rate,
                                  bool tag0 = true) {
  std::vector<std::pair<int, Eigen::Vector3d>> tags{{0, uwb.tag}};
  tags.insert(tags.end(), uwb.extra_tags.begin(), uwb.extra_tags.end());
  const double stagger = uwb.synchronous ? 0.0 : static_cast<double>(i) / static_cast<double>(n);
  std::vector<RangeSlot> slots;
  if (!uwb.tags_in_turn) {
    slots.push_back({stagger / rate, tags});
  } else {
    const auto m = static_cast<double>(tags.size());
    for (size_t j = 0; j < tags.size(); ++j)
      slots.push_back({(static_cast<double>(j) + stagger) / (rate * m), {tags[j]}});
  }
  if (!tag0)
    for (auto& slot : slots)
      slot.tags.erase(std::remove_if(slot.tags.begin(), slot.tags.end(),
                                     [](const auto& tag) { return tag.first == 0; }),
                      slot.tags.end());
  return slots;
}

// Every tag of `slot` ranges to `anchor` from the robot at `pose`.
void measureSlot(RangeModel& model, double t, const Eigen::Vector3d& pose, const RangeSlot& slot,
                 const uwb::Anchor& anchor, std::vector<loc::Event>& out,
                 std::vector<RangeTruth>* truth) {
  for (const auto& [id, tag] : slot.tags)
    model.measure(t, id, uwb::tagPosition(pose, tag), anchor, tag, out, truth);
}

// The manifest's tag keys: one tag as height and lever arm, several as tag_<id> keys.
void describeTags(const UwbSimSpec& uwb, ManifestDraft& m) {
  if (uwb.extra_tags.empty()) {
    m.tag_height = uwb.tag.z();
    m.lever_arm = uwb.tag.head<2>();
    return;
  }
  m.tags = uwb.extra_tags;
  m.tags[0] = uwb.tag;
}

// UWB: each anchor at its rate, staggered unless synchronous. Generated anchor by anchor and
// sorted by the caller; the draws follow the anchor order, so they are reproducible.
void simulateUwb(const Scenario& s, const TrajectorySampler& robot,
                 const std::optional<TrajectorySampler>& tag2, const loc::OccupancyMap* world,
                 Rng& rng_uwb, Simulation& sim) {
  const double t0 = s.start_time;
  RangeModel model(s.uwb, world, rng_uwb);
  for (size_t i = 0; i < s.anchors.size(); ++i) {
    const auto rate_it = s.uwb.anchor_rate.find(s.anchors[i].id);
    const double rate = rate_it != s.uwb.anchor_rate.end() ? rate_it->second : s.uwb.rate;
    const auto n_uwb = static_cast<long>(std::floor(s.duration * rate + 1e-9));
    const auto slots = rangeSlots(s.uwb, i, s.anchors.size(), rate);
    for (long k = 0; k <= n_uwb; ++k) {
      for (const auto& slot : slots) {
        const double t = k / rate + slot.offset;
        if (t > s.duration || inAny(s.uwb.dropouts, t)) continue;
        measureSlot(model, t0 + t, robot.pose(t), slot, s.anchors[i], sim.events, &sim.range_truth);
      }
      const double t = k / rate + slots.front().offset;
      if (tag2 && t <= s.duration && !inAny(s.uwb.dropouts, t)) {
        const Eigen::Vector3d pose = robot.pose(t);
        const Eigen::Vector3d p2 = tag2->pose(t);
        const Eigen::Vector3d tag2_world(p2.x(), p2.y(), s.tag2.height);
        const Eigen::Vector3d on_tag2(0.0, 0.0, s.tag2.height);
        model.measure(t0 + t, 1, tag2_world, s.anchors[i], on_tag2, sim.events, &sim.range_truth);
        if (i == 0) {  // once per round: the robot's tag ranges to the second tag
          const uwb::Anchor mobile{uwb::kMobileAnchorBase + 1, tag2_world};
          model.measure(t0 + t, 0, uwb::tagPosition(pose, s.uwb.tag), mobile, s.uwb.tag, sim.events,
                        &sim.range_truth);
        }
      }
    }
  }
  std::stable_sort(sim.range_truth.begin(), sim.range_truth.end(),
                   [](const RangeTruth& a, const RangeTruth& b) { return a.t < b.t; });
}

// Odometry: increments with noise growing with the motion.
void simulateOdometry(const Scenario& s, const TrajectorySampler& robot, Rng& rng_odo,
                      Simulation& sim) {
  const double t0 = s.start_time;
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto n = static_cast<long>(std::floor(s.duration * s.odometry.rate + 1e-9));
  Eigen::Vector3d last = robot.pose(0.0);
  for (long k = 1; k <= n; ++k) {
    const double t = k / s.odometry.rate;
    const Eigen::Vector3d now = robot.pose(t);
    const Eigen::Vector3d d = loc::relativePose(last, now);
    const double dist = d.head<2>().norm();
    const double sxy = s.odometry.sigma_xy_per_m * dist;
    const double sth =
        s.odometry.sigma_theta_per_rad * std::abs(d.z()) + s.odometry.sigma_theta_per_m * dist;
    const double gx = n01(rng_odo), gy = n01(rng_odo), gt = n01(rng_odo);
    loc::OdometryIncrement inc;
    inc.t = t0 + t;
    inc.delta << d.x() + sxy * gx, d.y() + sxy * gy, d.z() + sth * gt;
    sim.events.emplace_back(inc);
    last = now;
  }
}

// IMU: body-frame acceleration and yaw rate from the true motion, white noise, bias walk and
// vibration while driving. Each sample is the mean over the interval it closes, as an IMU's
// integrated (delta-velocity, delta-angle) output is: the path's speed changes in steps (it
// turns in place between straight legs), and a point derivative would miss the steps.
void simulateImu(const Scenario& s, const TrajectorySampler& robot, Rng& rng_imu, Simulation& sim) {
  const double t0 = s.start_time;
  std::normal_distribution<double> n01(0.0, 1.0);
  const double dt = 1.0 / s.imu.rate;
  const double h = 1e-4;  // differentiation step [s]
  auto velocity = [&](double t) {
    return Eigen::Vector2d(
        (robot.pose(t + h).head<2>() - robot.pose(std::max(t - h, 0.0)).head<2>()) /
        (t - h < 0.0 ? h : 2.0 * h));
  };
  Eigen::Vector2d accel_bias = Eigen::Vector2d::Zero();
  double gyro_bias = 0.0;
  const auto n = static_cast<long>(std::floor(s.duration * s.imu.rate + 1e-9));
  for (long k = 0; k <= n; ++k) {
    const double t = k * dt;
    const double t_prev = std::max(t - dt, 0.0);
    const Eigen::Vector3d p0 = robot.pose(t_prev), p1 = robot.pose(t);
    const double span = t - t_prev;
    const Eigen::Vector2d v1 = velocity(t);
    const Eigen::Vector2d acc_world =
        span > 0.0 ? Eigen::Vector2d((v1 - velocity(t_prev)) / span) : Eigen::Vector2d::Zero();
    // The body frame at the interval's start (the mechanisation rotates by the heading there).
    const Eigen::Vector2d acc_body = rotation(p0.z()).transpose() * acc_world;
    const double yaw_rate = span > 0.0 ? loc::wrapAngle(p1.z() - p0.z()) / span : 0.0;
    accel_bias +=
        s.imu.accel_bias_walk * std::sqrt(dt) * Eigen::Vector2d(n01(rng_imu), n01(rng_imu));
    gyro_bias += s.imu.gyro_bias_walk * std::sqrt(dt) * n01(rng_imu);
    loc::ImuSample imu;
    imu.t = t0 + t;
    imu.accel =
        acc_body + accel_bias + s.imu.accel_sigma * Eigen::Vector2d(n01(rng_imu), n01(rng_imu));
    imu.gyro_z = yaw_rate + gyro_bias + s.imu.gyro_sigma * n01(rng_imu);
    if (s.imu.vibration > 0.0 && v1.norm() > 0.01)
      imu.accel += s.imu.vibration * Eigen::Vector2d(n01(rng_imu), n01(rng_imu));
    sim.events.emplace_back(imu);
  }
}

// LiDAR: ray-cast scans with range noise.
void simulateLidar(const Scenario& s, const TrajectorySampler& robot,
                   const loc::OccupancyMap& world, Rng& rng_lidar, Simulation& sim) {
  const double t0 = s.start_time;
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto n = static_cast<long>(std::floor(s.duration * s.lidar.rate + 1e-9));
  for (long k = 0; k <= n; ++k) {
    const double t = k / s.lidar.rate;
    loc::LaserScan scan = castScan(world, robot.pose(t), s.lidar.params);
    scan.t = t0 + t;
    for (size_t i = 0; i < scan.ranges.size(); ++i) {
      const double g = n01(rng_lidar);
      if (scan.valid[i])
        scan.ranges[i] = static_cast<float>(scan.ranges[i] + s.lidar.params.sigma * g);
    }
    sim.events.emplace_back(std::move(scan));
  }
}

}  // namespace

Simulation simulate(const Scenario& s, uint64_t seed) {
  Simulation sim;
  const auto map = scenarioMap(s);
  const loc::OccupancyMap* world = map ? &*map : nullptr;
  // Independent streams per sensor, so enabling one sensor does not change another's noise.
  Rng rng_uwb(seed), rng_odo(seed ^ 0x9e3779b97f4a7c15ULL), rng_imu(seed ^ 0xbf58476d1ce4e5b9ULL),
      rng_lidar(seed ^ 0x94d049bb133111ebULL);
  const TrajectorySampler robot(s.trajectory);
  const std::optional<TrajectorySampler> tag2 =
      s.tag2.enabled ? std::optional<TrajectorySampler>(TrajectorySampler(s.tag2.trajectory))
                     : std::nullopt;
  const double t0 = s.start_time;
  // Ground truth.
  const auto gt_n = static_cast<long>(std::floor(s.duration * s.gt_rate + 1e-9));
  for (long k = 0; k <= gt_n; ++k) {
    const double t = k / s.gt_rate;
    sim.ground_truth.push_back({t0 + t, robot.pose(t)});
    if (tag2) sim.tag2_ground_truth.push_back({t0 + t, tag2->pose(t)});
  }

  simulateUwb(s, robot, tag2, world, rng_uwb, sim);
  if (s.odometry.rate > 0) simulateOdometry(s, robot, rng_odo, sim);
  if (s.imu.rate > 0) simulateImu(s, robot, rng_imu, sim);
  if (s.lidar.enabled && world) simulateLidar(s, robot, *world, rng_lidar, sim);
  loc::sortByTime(sim.events);
  return sim;
}

/// The recording's odometry integrated from the first increment: the pose at each increment's
/// time, in the odometry's own frame.
class OdometryTrack {
 public:
  explicit OdometryTrack(const std::vector<loc::Event>& events) {
    Eigen::Vector3d pose = Eigen::Vector3d::Zero();
    for (const auto& e : events) {
      const auto* inc = std::get_if<loc::OdometryIncrement>(&e);
      if (!inc || !inc->delta.allFinite()) continue;
      if (t_.empty()) {  // the first increment's motion began at an unknown time
        t_.push_back(inc->t);
        poses_.push_back(pose);
        continue;
      }
      if (inc->t < t_.back()) continue;
      pose = loc::composePose(pose, inc->delta);
      t_.push_back(inc->t);
      poses_.push_back(pose);
    }
  }
  /// The pose at time t, linear between the increments' times; nothing outside them.
  std::optional<Eigen::Vector3d> at(double t) const {
    if (t_.size() < 2 || t < t_.front() || t > t_.back()) return std::nullopt;
    const auto k = static_cast<size_t>(std::upper_bound(t_.begin(), t_.end(), t) - t_.begin());
    if (k >= t_.size()) return poses_.back();
    const double span = t_[k] - t_[k - 1];
    const double w = span > 0.0 ? (t - t_[k - 1]) / span : 1.0;
    const Eigen::Vector3d d = loc::relativePose(poses_[k - 1], poses_[k]);
    return loc::composePose(poses_[k - 1], Eigen::Vector3d(w * d.x(), w * d.y(), w * d.z()));
  }

 private:
  std::vector<double> t_;
  std::vector<Eigen::Vector3d> poses_;
};

PathBetweenPoses::PathBetweenPoses(const std::vector<loc::Event>& events)
    : odometry_(std::make_shared<OdometryTrack>(events)) {}

Eigen::Vector3d PathBetweenPoses::at(const TimedPose& a, const TimedPose& b, double t) {
  const double w = (t - a.t) / (b.t - a.t);
  const auto oa = odometry_->at(a.t), ob = odometry_->at(b.t), ot = odometry_->at(t);
  if (oa && ob && ot) {
    // The odometry's shape from a, and what it misses at b spread over the interval in time.
    const Eigen::Vector3d end = loc::composePose(a.pose, loc::relativePose(*oa, *ob));
    Eigen::Vector3d miss = b.pose - end;
    miss.z() = loc::wrapAngle(miss.z());
    const double moved = (b.pose - a.pose).head<2>().norm();
    if (miss.head<2>().norm() <= kMaxMissXy + kMaxMissPerMetre * moved &&
        std::abs(miss.z()) <= kMaxMissTheta) {
      ++odometry_shaped_;
      Eigen::Vector3d pose = loc::composePose(a.pose, loc::relativePose(*oa, *ot)) + w * miss;
      pose.z() = loc::wrapAngle(pose.z());
      return pose;
    }
  }
  ++straight_;
  Eigen::Vector3d pose = a.pose + w * (b.pose - a.pose);
  pose.z() = loc::wrapAngle(a.pose.z() + w * loc::wrapAngle(b.pose.z() - a.pose.z()));
  return pose;
}

std::vector<loc::Event> augmentWithUwb(const std::vector<loc::Event>& events,
                                       const std::vector<TimedPose>& reference,
                                       const std::vector<uwb::Anchor>& anchors,
                                       const UwbSimSpec& uwb, const loc::OccupancyMap* map,
                                       uint64_t seed, std::vector<RangeTruth>* truth,
                                       double max_gap, bool simulate_tag0, PathBetweenPoses* path) {
  std::vector<loc::Event> out = events;
  if (reference.size() < 2) return out;
  Rng rng(seed);
  RangeModel model(uwb, map, rng);
  PathBetweenPoses own(events);
  if (!path) path = &own;
  const double start = reference.front().t, end = reference.back().t;
  const auto n = static_cast<long>(std::floor((end - start) * uwb.rate));
  std::vector<std::vector<RangeSlot>> slots;
  for (size_t i = 0; i < anchors.size(); ++i)
    slots.push_back(rangeSlots(uwb, i, anchors.size(), uwb.rate, simulate_tag0));
  for (long k = 0; k <= n; ++k) {
    for (size_t i = 0; i < anchors.size(); ++i) {
      for (const auto& slot : slots[i]) {
        const double t = start + k / uwb.rate + slot.offset;
        if (slot.tags.empty() || t > end || inAny(uwb.dropouts, t - start)) continue;
        // The reference poses around t (tags in turn take the slots out of time order).
        const auto after =
            std::lower_bound(reference.begin(), reference.end(), t,
                             [](const TimedPose& p, double time) { return p.t < time; });
        const size_t j = std::min(
            static_cast<size_t>(std::max<std::ptrdiff_t>(after - reference.begin() - 1, 0)),
            reference.size() - 2);
        const auto& a = reference[j];
        const auto& b = reference[j + 1];
        // Do not invent poses across gaps in the reference.
        if (b.t - a.t > max_gap || t < a.t || t > b.t) continue;
        measureSlot(model, t, path->at(a, b, t), slot, anchors[i], out, truth);
      }
    }
  }
  loc::sortByTime(out);
  return out;
}

std::string writeAugmented(const AugmentRequest& req, const std::string& out_dir) {
  Recording rec = readRawlog(req.rawlog);
  if (const auto w = collapsedTimeWarning(rec.events); w && !req.allow_bad_time)
    throwInputError(req.rawlog, 0, *w + " (--allow-bad-time augments it anyway)");
  const bool tum =
      req.reference.size() > 4 && req.reference.substr(req.reference.size() - 4) == ".tum";
  const auto reference =
      readGroundTruth(req.reference, tum ? GroundTruthFormat::kTum : GroundTruthFormat::kTimeXyPhi);
  const auto anchors = loadAnchorsCsv(req.anchors_csv);
  UwbSimSpec uwb;
  if (!req.scenario.empty()) uwb = loadScenario(req.scenario).uwb;

  std::optional<loc::OccupancyMap> map;
  if (req.map == "scans") {
    // Map the recording's own scans at the reference poses.
    std::vector<const loc::LaserScan*> scans;
    std::vector<Eigen::Vector3d> poses;
    size_t j = 0;
    for (const auto& e : rec.events) {
      const auto* scan = std::get_if<loc::LaserScan>(&e);
      if (!scan) continue;
      while (j + 1 < reference.size() && reference[j + 1].t <= scan->t) ++j;
      if (std::abs(reference[j].t - scan->t) > 0.05) continue;
      scans.push_back(scan);
      poses.push_back(reference[j].pose);
    }
    map = mapFromScans(scans, poses, req.map_resolution);
  } else if (!req.map.empty()) {
    try {
      map = loc::OccupancyMap::load(req.map);
    } catch (const std::runtime_error& e) {
      throw InputError(e.what());
    }
  }
  // A recording that has its own tag's ranges keeps them: only the extra tags are simulated,
  // and the manifest keeps tag 0 where the recording has it.
  const uwb::Range* own = nullptr;
  for (const auto& e : rec.events)
    if (const auto* r = std::get_if<uwb::Range>(&e); r && r->tag_id == 0 && !own) own = r;
  const bool simulate_tag0 = !own || uwb.extra_tags.empty();
  std::vector<RangeTruth> truth;
  PathBetweenPoses path(rec.events);
  const auto events = augmentWithUwb(rec.events, reference, anchors, uwb, map ? &*map : nullptr,
                                     req.seed, &truth, req.max_gap, simulate_tag0, &path);

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "augmented.rawlog").string(), events);
  writeFileAtomic((out / "reference.txt").string(), formatTimeXyPhi(reference));
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(anchors));
  long nlos = 0;
  for (const auto& r : truth) nlos += r.nlos;
  writeFileAtomic((out / "range_truth.csv").string(), formatRangeTruth(truth));
  if (map) map->save((out / "map.gridmap.gz").string());
  ManifestDraft m;
  m.comments = {"Written by 'uwbloc augment': " + std::to_string(truth.size()) +
                    " simulated ranges (" + std::to_string(nlos) + " NLOS), seed " +
                    std::to_string(req.seed),
                "Poses between the reference's: " + std::to_string(path.odometryShaped()) +
                    " along the recording's odometry, " + std::to_string(path.straight()) +
                    " on a straight line (no odometry there, or odometry that misses the next "
                    "reference pose)"};
  m.name = "augmented_" + fs::path(req.rawlog).stem().string();
  m.rawlog = "augmented.rawlog";
  m.ground_truth = "reference.txt";
  m.ground_truth_format = GroundTruthFormat::kTimeXyPhi;
  m.gt_max_gap = req.max_gap;
  if (map) m.map = "map.gridmap.gz";
  m.anchors_csv = "anchors.csv";
  describeTags(uwb, m);
  if (!simulate_tag0) {
    m.tags[0] = own->tag_on_robot;
    m.comments.push_back("Tag 0's ranges are the recording's own; tags " + [&] {
      std::string ids;
      for (const auto& [id, p] : uwb.extra_tags)
        ids += (ids.empty() ? "" : ", ") + std::to_string(id);
      return ids;
    }() + " are simulated");
  }
  m.bounds_range_sigma = uwb.sigma;
  const std::string manifest = writeManifest(out_dir, m);
  return manifest;
}

std::string writeSimulation(const Scenario& s, uint64_t seed, const std::string& out_dir) {
  const Simulation sim = simulate(s, seed);
  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "sim.rawlog").string(), sim.events);
  writeFileAtomic((out / "ground_truth.tum").string(), formatTum(sim.ground_truth));
  writeFileAtomic((out / "ground_truth.txt").string(), formatTimeXyPhi(sim.ground_truth));
  if (!sim.tag2_ground_truth.empty())
    writeFileAtomic((out / "tag2_ground_truth.tum").string(), formatTum(sim.tag2_ground_truth));

  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(s.anchors));
  writeFileAtomic((out / "range_truth.csv").string(), formatRangeTruth(sim.range_truth));

  if (s.uwb.features) {
    // The features with each range's truth and NLOS flag: a labelled set for 'uwbloc nlos'.
    std::map<std::tuple<long long, int, int>, const RangeTruth*> by_key;
    for (const auto& g : sim.range_truth)
      by_key[{std::llround(g.t * 1e6), g.tag_id, g.anchor_id}] = &g;
    std::vector<RangeLabel> labels(sim.events.size());
    for (size_t i = 0; i < sim.events.size(); ++i)
      if (const auto* r = std::get_if<uwb::Range>(&sim.events[i])) {
        const auto it = by_key.find({std::llround(r->t * 1e6), r->tag_id, r->anchor_id});
        if (it != by_key.end()) labels[i] = {it->second->true_range, it->second->nlos ? 1 : 0};
      }
    writeFileAtomic((out / "range_features.csv").string(),
                    formatRangeFeatures(sim.events, &labels));
  }

  const auto map = scenarioMap(s);
  if (map) map->save((out / "map.gridmap.gz").string());

  ManifestDraft m;
  m.comments = {"Written by 'uwbloc simulate' from " + fs::path(s.path).filename().string() +
                ", seed " + std::to_string(seed)};
  m.name = "sim_" + s.name;
  m.rawlog = "sim.rawlog";
  m.ground_truth = "ground_truth.tum";
  m.ground_truth_format = GroundTruthFormat::kTum;
  if (map) m.map = "map.gridmap.gz";
  if (s.uwb.features) m.range_features = "range_features.csv";
  m.anchors_csv = "anchors.csv";
  describeTags(s.uwb, m);
  m.bounds_range_sigma = s.uwb.sigma;
  if (s.odometry.rate > 0)
    m.bounds_odometry = Eigen::Vector3d(s.odometry.sigma_xy_per_m, s.odometry.sigma_theta_per_rad,
                                        s.odometry.sigma_theta_per_m);
  const std::string manifest = writeManifest(out_dir, m);
  return manifest;
}

}  // namespace uwbloc::data
