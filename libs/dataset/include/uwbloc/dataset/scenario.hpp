// Simulation scenarios: one INI file describing a world, anchors, a trajectory and the sensors.
// See datasets/scenarios/README.md for every key; unknown keys are errors naming the line.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "uwbloc/dataset/world.hpp"
#include "uwbloc/localization/lidar/occupancy_map.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::data {

using Interval = std::pair<double, double>;  ///< [start, end] in seconds from the run's start

/// A path: waypoints driven in order at `speed`, turning in place at `turn_rate` at each corner.
struct TrajectorySpec {
  std::vector<Eigen::Vector2d> waypoints;
  bool closed = true;            ///< return to the first waypoint and repeat
  double speed = 0.5;            ///< [m/s]
  double turn_rate = 1.0;        ///< [rad/s]
  std::vector<Interval> pauses;  ///< the robot stands still during these
  int waypoints_line = 0;        ///< for error messages
};

struct UwbSimSpec {
  double rate = 10.0;                 ///< ranges per second per anchor [Hz]
  std::map<int, double> anchor_rate;  ///< per-anchor overrides of `rate` [Hz]
  bool synchronous = false;           ///< all anchors at the same instants (else staggered)
  double sigma = 0.1;                 ///< LOS noise std [m]
  double sigma_per_m = 0.0;           ///< added to sigma per metre of range
  double bias = 0.0;                  ///< LOS noise mean [m]
  std::string nlos_distribution = "exponential";  ///< exponential | uniform | constant
  double nlos_mean = 0.5;                         ///< mean positive NLOS bias [m]
  std::vector<Interval> dropouts;                 ///< no ranges inside these
  double outlier_prob = 0.0;                      ///< probability of a gross outlier
  double outlier_max = 5.0;           ///< outlier magnitude ~ U(1, outlier_max), random sign [m]
  double zero_prob = 0.0;             ///< probability of a zero reading
  std::map<int, double> anchor_bias;  ///< constant bias per anchor id [m]
  bool features = false;              ///< write received and first-path power
  Eigen::Vector3d tag = Eigen::Vector3d(0, 0, 1.0);  ///< tag on the robot [m]
  /// More tags on the robot ([uwb] tag_<id> = x y z; id 1 is the [tag2] mobile node's): each
  /// ranges to every anchor at the same instants as tag 0, unless tags_in_turn.
  std::map<int, Eigen::Vector3d> extra_tags;
  /// Several tags range in turn (time-division: each tag has its own slot of every round, tag 0
  /// first, then the others by id, the anchors staggered within it unless synchronous) instead
  /// of together.
  bool tags_in_turn = false;
  double max_range = 60.0;  ///< no ranges beyond this [m]
};

struct OdometrySimSpec {
  double rate = 10.0;                 ///< [Hz]; 0 disables
  double sigma_xy_per_m = 0.02;       ///< translation noise std per metre moved
  double sigma_theta_per_rad = 0.02;  ///< rotation noise std per radian turned
  double sigma_theta_per_m = 0.005;   ///< rotation noise std per metre moved [rad/m]
};

struct ImuSimSpec {
  double rate = 0.0;               ///< [Hz]; 0 disables
  double accel_sigma = 0.05;       ///< white noise [m/s^2]
  double gyro_sigma = 0.005;       ///< white noise [rad/s]
  double accel_bias_walk = 0.002;  ///< bias random walk [m/s^2 per sqrt(s)]
  double gyro_bias_walk = 0.0002;  ///< bias random walk [rad/s per sqrt(s)]
  /// Accelerometer vibration while the robot drives (speed above 1 cm/s) [m/s^2 std]: what a
  /// stationarity detector tells rest from constant velocity by.
  double vibration = 0.0;
};

struct LidarSimSpec {
  bool enabled = false;
  double rate = 10.0;  ///< [Hz]
  LidarParams params;
};

/// A second, slow tag (the mobile-node paper): it ranges to the anchors and the robot's tag
/// ranges to it (anchor id uwb::kMobileAnchorBase + 1).
struct SecondTagSpec {
  bool enabled = false;
  TrajectorySpec trajectory;
  double height = 1.0;
};

struct Scenario {
  std::string path;
  std::string name;
  double duration = 0.0;      ///< [s]; 0 = one lap of a closed path
  double gt_rate = 10.0;      ///< ground-truth samples per second
  double start_time = 1.7e9;  ///< timestamp of t = 0 [s]
  // World: a map file, or a rectangle with rectangular obstacles, or nothing (open field).
  std::string map_file;
  double map_resolution = 0.05;
  Eigen::Vector2d map_origin = Eigen::Vector2d::Zero();
  std::optional<loc::Rect> bounds;
  std::vector<loc::Rect> obstacles;
  bool walls = true;
  std::vector<uwb::Anchor> anchors;
  TrajectorySpec trajectory;
  UwbSimSpec uwb;
  OdometrySimSpec odometry;
  ImuSimSpec imu;
  LidarSimSpec lidar;
  SecondTagSpec tag2;
  std::vector<std::string> warnings;  ///< e.g. an anchor on an occupied cell
};

/// Loads and validates a scenario (unknown keys, no anchors, waypoints outside the map or inside
/// an obstacle are errors naming the file and line). Builds the world map when there is one.
Scenario loadScenario(const std::string& path);

/// The world of a scenario: the map file, or the rectangles; nothing for an open field.
std::optional<loc::OccupancyMap> scenarioMap(const Scenario& s);

/// Ground-truth pose (x, y, theta) at time t [s from start] along a trajectory.
class TrajectorySampler {
 public:
  explicit TrajectorySampler(const TrajectorySpec& spec);
  Eigen::Vector3d pose(double t) const;
  /// Time to drive the path once (no pauses) [s].
  double lapTime() const { return lap_time_; }

 private:
  struct Phase {
    double t0, duration;
    Eigen::Vector3d start, end;
  };
  double motionTime(double t) const;  ///< t minus the pauses before it
  std::vector<Phase> phases_;
  double lap_time_ = 0.0;
  bool closed_ = true;
  std::vector<Interval> pauses_;
  Eigen::Vector3d first_ = Eigen::Vector3d::Zero();
};

}  // namespace uwbloc::data
