#include "uwbloc/dataset/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ini_file.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/events.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

// Parses "a b c" into exactly n numbers (n = 0: any count).
std::vector<double> numbers(const IniFile& ini, const std::string& section, const std::string& key,
                            size_t n) {
  const std::string text = *ini.get(section, key);
  std::istringstream in(text);
  std::vector<double> out;
  std::string item;
  while (in >> item) out.push_back(parseNumber(item, ini.path(), ini.lineOf(section, key), key));
  if (n != 0 && out.size() != n)
    throwInputError(ini.path(), ini.lineOf(section, key),
                    "'" + key + "' expects " + std::to_string(n) + " numbers, got '" + text + "'");
  return out;
}

// Parses "a b, c d, ..." into pairs (';' starts a comment in MRPT-style INI files).
std::vector<std::pair<double, double>> pairs(const IniFile& ini, const std::string& section,
                                             const std::string& key) {
  std::vector<std::pair<double, double>> out;
  const auto text = ini.get(section, key);
  if (!text) return out;
  std::istringstream in(*text);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (item.find_first_not_of(" \t") == std::string::npos) continue;
    std::istringstream cell(item);
    std::string a, b, extra;
    if (!(cell >> a >> b) || (cell >> extra))
      throwInputError(ini.path(), ini.lineOf(section, key),
                      "'" + key + "' expects 'a b, c d, ...', got '" + item + "'");
    out.emplace_back(parseNumber(a, ini.path(), ini.lineOf(section, key), key),
                     parseNumber(b, ini.path(), ini.lineOf(section, key), key));
  }
  return out;
}

bool boolean(const IniFile& ini, const std::string& section, const std::string& key,
             bool fallback) {
  const auto v = ini.get(section, key);
  if (!v) return fallback;
  if (*v == "1" || *v == "true" || *v == "yes") return true;
  if (*v == "0" || *v == "false" || *v == "no") return false;
  throwInputError(ini.path(), ini.lineOf(section, key),
                  "'" + key + "' expects 0 or 1, got '" + *v + "'");
}

void readDouble(const IniFile& ini, const std::string& section, const std::string& key, double& v) {
  v = ini.getDouble(section, key, v);
}

TrajectorySpec readTrajectory(const IniFile& ini, const std::string& section) {
  TrajectorySpec t;
  if (!ini.get(section, "waypoints"))
    throwInputError(ini.path(), 0, "missing key 'waypoints' in section [" + section + "]");
  for (const auto& [x, y] : pairs(ini, section, "waypoints")) t.waypoints.emplace_back(x, y);
  t.waypoints_line = ini.lineOf(section, "waypoints");
  if (t.waypoints.empty()) throwInputError(ini.path(), t.waypoints_line, "no waypoints");
  t.closed = boolean(ini, section, "closed", t.closed);
  readDouble(ini, section, "speed", t.speed);
  readDouble(ini, section, "turn_rate", t.turn_rate);
  if (!(t.speed > 0) || !(t.turn_rate > 0))
    throwInputError(ini.path(), ini.lineOf(section, "speed"), "speed and turn_rate must be > 0");
  t.pauses = pairs(ini, section, "pauses");
  return t;
}

}  // namespace

TrajectorySampler::TrajectorySampler(const TrajectorySpec& spec)
    : closed_(spec.closed), pauses_(spec.pauses) {
  std::vector<Eigen::Vector2d> pts = spec.waypoints;
  if (spec.closed && pts.size() > 1) pts.push_back(pts.front());
  // Start facing the first leg.
  double heading =
      pts.size() > 1 ? std::atan2(pts[1].y() - pts[0].y(), pts[1].x() - pts[0].x()) : 0.0;
  first_ << pts.front(), heading;
  double t = 0.0;
  for (size_t i = 0; i + 1 < pts.size(); ++i) {
    const Eigen::Vector2d d = pts[i + 1] - pts[i];
    if (d.norm() < 1e-9) continue;
    const double leg_heading = std::atan2(d.y(), d.x());
    const double turn = loc::wrapAngle(leg_heading - heading);
    if (std::abs(turn) > 1e-9) {  // turn in place at the corner
      const double dur = std::abs(turn) / spec.turn_rate;
      phases_.push_back(
          {t, dur, {pts[i].x(), pts[i].y(), heading}, {pts[i].x(), pts[i].y(), heading + turn}});
      t += dur;
      heading += turn;
    }
    const double dur = d.norm() / spec.speed;
    phases_.push_back(
        {t, dur, {pts[i].x(), pts[i].y(), heading}, {pts[i + 1].x(), pts[i + 1].y(), heading}});
    t += dur;
  }
  if (spec.closed && !phases_.empty()) {  // turn back to the starting heading
    const double turn = loc::wrapAngle(first_.z() - heading);
    if (std::abs(turn) > 1e-9) {
      const double dur = std::abs(turn) / spec.turn_rate;
      const Eigen::Vector2d p = pts.back();
      phases_.push_back({t, dur, {p.x(), p.y(), heading}, {p.x(), p.y(), heading + turn}});
      t += dur;
    }
  }
  lap_time_ = t;
}

double TrajectorySampler::motionTime(double t) const {
  double paused = 0.0;
  for (const auto& [a, b] : pauses_) {
    if (t <= a) continue;
    paused += std::min(t, b) - a;
  }
  return t - paused;
}

Eigen::Vector3d TrajectorySampler::pose(double t) const {
  if (phases_.empty()) return first_;
  double m = motionTime(t);
  if (closed_) {
    m = std::fmod(std::max(m, 0.0), lap_time_);
  } else if (m >= lap_time_) {
    Eigen::Vector3d end = phases_.back().end;
    end.z() = loc::wrapAngle(end.z());
    return end;
  }
  for (const auto& ph : phases_) {
    if (m > ph.t0 + ph.duration) continue;
    const double a = std::clamp((m - ph.t0) / ph.duration, 0.0, 1.0);
    Eigen::Vector3d p = ph.start + a * (ph.end - ph.start);
    p.z() = loc::wrapAngle(p.z());
    return p;
  }
  return phases_.back().end;
}

std::optional<loc::OccupancyMap> scenarioMap(const Scenario& s) {
  if (!s.map_file.empty()) {
    try {
      return loc::OccupancyMap::load(s.map_file, s.map_resolution, s.map_origin);
    } catch (const std::runtime_error& e) {
      throw InputError(s.path + ": [world] map: " + e.what());
    }
  }
  if (s.bounds) return mapFromRectangles(*s.bounds, s.obstacles, s.map_resolution, s.walls);
  return std::nullopt;
}

namespace {

// [world]: a map file, or bounds with rectangular obstacles.
void readWorld(const IniFile& ini, const std::string& path, Scenario& s) {
  const std::string dir = fs::path(path).parent_path().string();
  if (const auto m = ini.get("world", "map")) {
    s.map_file = fs::path(*m).is_absolute() ? *m : (fs::path(dir) / *m).lexically_normal().string();
  }
  readDouble(ini, "world", "resolution", s.map_resolution);
  if (ini.get("world", "origin")) {
    const auto o = numbers(ini, "world", "origin", 2);
    s.map_origin = {o[0], o[1]};
  }
  if (ini.get("world", "bounds")) {
    const auto b = numbers(ini, "world", "bounds", 4);
    s.bounds = loc::Rect{b[0], b[1], b[2], b[3]};
  }
  s.walls = boolean(ini, "world", "walls", s.walls);
  for (const auto& key : ini.keys("world")) {
    if (key.rfind("obstacle_", 0) != 0) continue;
    const auto r = numbers(ini, "world", key, 4);
    s.obstacles.push_back({r[0], r[1], r[2], r[3]});
  }
  if (!s.obstacles.empty() && !s.bounds)
    throwInputError(path, 0, "[world] obstacles need 'bounds = xmin ymin xmax ymax'");
  // Limits that keep the grid in memory: resolution 1 mm .. 10 m, a world of at most 10 km a
  // side and 1e8 cells.
  if (!(s.map_resolution >= 1e-3 && s.map_resolution <= 10.0))
    throwInputError(path, ini.lineOf("world", "resolution"),
                    "[world] resolution must be in [0.001, 10] m");
  if (s.bounds) {
    const auto& b = *s.bounds;
    const double w = b.xmax - b.xmin, h = b.ymax - b.ymin;
    if (!(w > 0 && h > 0 && w <= 1e4 && h <= 1e4 && std::abs(b.xmin) <= 1e5 &&
          std::abs(b.ymin) <= 1e5))
      throwInputError(
          path, ini.lineOf("world", "bounds"),
          "[world] bounds must span (0, 10 000] m each way, within 100 km of the origin");
    if (w * h / (s.map_resolution * s.map_resolution) > 1e8)
      throwInputError(path, ini.lineOf("world", "bounds"),
                      "[world] bounds / resolution give over 1e8 cells");
  }
}

// [anchors]: anchor_<id> = x y z.
void readAnchors(const IniFile& ini, const std::string& path, Scenario& s) {
  for (const auto& key : ini.keys("anchors")) {
    if (key.rfind("anchor_", 0) != 0) continue;  // left unread: reported as unknown below
    const int line = ini.lineOf("anchors", key);
    const int id = parseId(key.substr(7), path, line, key + " (id)");
    const auto p = numbers(ini, "anchors", key, 3);
    s.anchors.push_back({id, {p[0], p[1], p[2]}});
  }
  if (s.anchors.empty()) throwInputError(path, 0, "no anchors: add [anchors] anchor_<id> = x y z");
}

// [uwb]: the range model (rate, noise, bias, NLOS, dropouts, outliers, features, tag).
void readUwb(const IniFile& ini, const std::string& path, Scenario& s) {
  auto& u = s.uwb;
  readDouble(ini, "uwb", "rate", u.rate);
  u.synchronous = boolean(ini, "uwb", "synchronous", u.synchronous);
  u.tags_in_turn = boolean(ini, "uwb", "tags_in_turn", u.tags_in_turn);
  readDouble(ini, "uwb", "sigma", u.sigma);
  readDouble(ini, "uwb", "sigma_per_m", u.sigma_per_m);
  readDouble(ini, "uwb", "bias", u.bias);
  u.nlos_distribution = ini.getString("uwb", "nlos_distribution", u.nlos_distribution);
  if (u.nlos_distribution != "exponential" && u.nlos_distribution != "uniform" &&
      u.nlos_distribution != "constant")
    throwInputError(path, ini.lineOf("uwb", "nlos_distribution"),
                    "nlos_distribution must be exponential, uniform or constant");
  readDouble(ini, "uwb", "nlos_mean", u.nlos_mean);
  u.dropouts = pairs(ini, "uwb", "dropouts");
  readDouble(ini, "uwb", "outlier_prob", u.outlier_prob);
  readDouble(ini, "uwb", "outlier_max", u.outlier_max);
  readDouble(ini, "uwb", "zero_prob", u.zero_prob);
  for (const auto& key : ini.keys("uwb"))
    if (key.rfind("rate_", 0) == 0) {
      const double rate = ini.getDouble("uwb", key);
      if (!(rate > 0)) throwInputError(path, ini.lineOf("uwb", key), "'" + key + "' must be > 0");
      u.anchor_rate[parseId(key.substr(5), path, ini.lineOf("uwb", key), key)] = rate;
    }
  for (const auto& key : ini.keys("uwb"))
    if (key.rfind("bias_", 0) == 0)
      u.anchor_bias[parseId(key.substr(5), path, ini.lineOf("uwb", key), key)] =
          ini.getDouble("uwb", key);
  u.features = boolean(ini, "uwb", "features", u.features);
  if (ini.get("uwb", "tag")) {
    const auto t = numbers(ini, "uwb", "tag", 3);
    u.tag = {t[0], t[1], t[2]};
  }
  for (const auto& key : ini.keys("uwb"))
    if (key.rfind("tag_", 0) == 0) {
      const int id = parseId(key.substr(4), path, ini.lineOf("uwb", key), key);
      if (id == 0) throwInputError(path, ini.lineOf("uwb", key), "tag 0 is the robot's 'tag' key");
      const auto t = numbers(ini, "uwb", key, 3);
      u.extra_tags[id] = {t[0], t[1], t[2]};
    }
  readDouble(ini, "uwb", "max_range", u.max_range);
  if (!(u.rate > 0) || !(u.sigma >= 0))
    throwInputError(path, ini.lineOf("uwb", "rate"), "[uwb] rate must be > 0 and sigma >= 0");
}

// [odometry] and [imu]: their rates and noise.
void readMotionSensors(const IniFile& ini, Scenario& s) {
  readDouble(ini, "odometry", "rate", s.odometry.rate);
  readDouble(ini, "odometry", "sigma_xy_per_m", s.odometry.sigma_xy_per_m);
  readDouble(ini, "odometry", "sigma_theta_per_rad", s.odometry.sigma_theta_per_rad);
  readDouble(ini, "odometry", "sigma_theta_per_m", s.odometry.sigma_theta_per_m);

  readDouble(ini, "imu", "rate", s.imu.rate);
  readDouble(ini, "imu", "accel_sigma", s.imu.accel_sigma);
  readDouble(ini, "imu", "gyro_sigma", s.imu.gyro_sigma);
  readDouble(ini, "imu", "accel_bias_walk", s.imu.accel_bias_walk);
  readDouble(ini, "imu", "gyro_bias_walk", s.imu.gyro_bias_walk);
  readDouble(ini, "imu", "vibration", s.imu.vibration);
}

// [lidar]: a preset and its overrides.
void readLidar(const IniFile& ini, const std::string& path, Scenario& s) {
  if (const auto preset = ini.get("lidar", "preset")) {
    s.lidar.enabled = *preset != "none";
    if (s.lidar.enabled) {
      try {
        s.lidar.params = LidarParams::preset(*preset);
      } catch (const std::runtime_error& e) {
        throwInputError(path, ini.lineOf("lidar", "preset"), e.what());
      }
    }
    readDouble(ini, "lidar", "rate", s.lidar.rate);
    double rays = s.lidar.params.rays, fov_deg = s.lidar.params.fov * 180.0 / M_PI;
    readDouble(ini, "lidar", "rays", rays);
    readDouble(ini, "lidar", "fov_deg", fov_deg);
    if (!(rays >= 1 && rays <= 1e5))
      throwInputError(path, ini.lineOf("lidar", "rays"), "[lidar] rays must be in [1, 100000]");
    s.lidar.params.rays = static_cast<int>(rays);
    s.lidar.params.fov = fov_deg * M_PI / 180.0;
    readDouble(ini, "lidar", "min_range", s.lidar.params.min_range);
    readDouble(ini, "lidar", "max_range", s.lidar.params.max_range);
    readDouble(ini, "lidar", "sigma", s.lidar.params.sigma);
  }
}

// The trajectories and anchors against the world; the duration of a lap when none is given.
void validateScenario(const IniFile& ini, const std::string& path, Scenario& s) {
  if (s.tag2.enabled && s.uwb.extra_tags.count(1))
    throwInputError(path, ini.lineOf("uwb", "tag_1"),
                    "tag id 1 is the [tag2] mobile node's: number the robot's tags from 2");
  const auto map = scenarioMap(s);
  if (s.lidar.enabled && !map)
    throwInputError(path, ini.lineOf("lidar", "preset"), "a LiDAR needs a [world] map or bounds");
  if (map) {
    auto checkPath = [&](const TrajectorySpec& t, const char* section) {
      for (const auto& w : t.waypoints) {
        std::ostringstream where;
        where << "waypoint (" << w.x() << ", " << w.y() << ") of [" << section << "]";
        if (!map->inside(w))
          throwInputError(path, t.waypoints_line, where.str() + " is outside the map");
        if (map->occupied(w))
          throwInputError(path, t.waypoints_line, where.str() + " is inside an obstacle");
      }
    };
    checkPath(s.trajectory, "trajectory");
    if (s.tag2.enabled) checkPath(s.tag2.trajectory, "tag2");
    for (const auto& a : s.anchors)
      if (map->occupied(a.position.head<2>()))
        s.warnings.push_back("anchor " + std::to_string(a.id) +
                             " stands on an occupied cell (wall-mounted?); its own cell is not "
                             "counted as an obstruction");
  }
  if (s.duration <= 0.0) {
    const double lap = TrajectorySampler(s.trajectory).lapTime();
    if (lap <= 0.0) throwInputError(path, 0, "a stationary trajectory needs [scenario] duration");
    double paused = 0.0;
    for (const auto& [a, b] : s.trajectory.pauses) paused += b - a;
    s.duration = lap + paused;
  }
}

}  // namespace

Scenario loadScenario(const std::string& path) {
  const IniFile ini = IniFile::load(path);
  Scenario s;
  s.path = path;
  s.name = ini.getString("scenario", "name", fs::path(path).stem().string());
  readDouble(ini, "scenario", "duration", s.duration);
  readDouble(ini, "scenario", "gt_rate", s.gt_rate);
  readDouble(ini, "scenario", "start_time", s.start_time);
  readWorld(ini, path, s);
  readAnchors(ini, path, s);
  s.trajectory = readTrajectory(ini, "trajectory");
  readUwb(ini, path, s);
  readMotionSensors(ini, s);
  readLidar(ini, path, s);
  if (ini.hasSection("tag2")) {
    s.tag2.enabled = true;
    s.tag2.trajectory = readTrajectory(ini, "tag2");
    readDouble(ini, "tag2", "height", s.tag2.height);
  }
  ini.rejectUnread();
  validateScenario(ini, path, s);
  return s;
}

}  // namespace uwbloc::data
