// The simulator: a scenario and a seed in, an ordinary dataset out (rawlog, ground truth,
// anchors, map, manifest), so everything downstream stays the same. The same seed gives
// byte-identical files.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/localization/events.hpp"

namespace uwbloc::data {

/// Ground truth of one simulated range, written to range_truth.csv.
struct RangeTruth {
  double t = 0.0;
  int tag_id = 0, anchor_id = 0;
  double true_range = 0.0;
  double error = 0.0;  ///< measured minus true (for zero readings, -true_range)
  bool nlos = false;   ///< the tag-anchor segment crossed an occupied cell
};

struct Simulation {
  std::vector<loc::Event> events;       ///< time-ordered
  std::vector<TimedPose> ground_truth;  ///< robot poses at gt_rate
  std::vector<TimedPose> tag2_ground_truth;
  std::vector<RangeTruth> range_truth;
};

/// Generates the recordings of a scenario (no files).
Simulation simulate(const Scenario& scenario, uint64_t seed);

/// simulate() and write: sim.rawlog, ground_truth.tum, ground_truth.txt (time x y phi),
/// anchors.csv, range_truth.csv, range_features.csv (when enabled), map.gridmap.gz (when there
/// is a world), tag2_ground_truth.tum (when there is a second tag) and dataset.ini.
/// Returns the manifest path.
std::string writeSimulation(const Scenario& scenario, uint64_t seed, const std::string& out_dir);

/// Where the robot was between two reference poses a and b (a.t <= t <= b.t). Along the
/// recording's own odometry when it covers the interval: its path from a, with what it misses
/// at b spread linearly over the time between (the odometry drifts little over one interval,
/// but a straight line cuts every curve: on CARMEN intel, whose reference poses are 3.4 s apart,
/// the chord lies 0.13 m from the odometry's path at the median interval's widest point and
/// 0.36 m at the 90th percentile). A straight line (heading interpolated) where the odometry
/// does not cover the interval, or misses b by more than the limits below (odometry that cannot
/// be trusted there).
class OdometryTrack;
class PathBetweenPoses {
 public:
  static constexpr double kMaxMissXy = 0.3;        ///< [m], plus:
  static constexpr double kMaxMissPerMetre = 0.2;  ///< per metre between a and b
  static constexpr double kMaxMissTheta = 0.35;    ///< [rad] (20 deg)

  explicit PathBetweenPoses(const std::vector<loc::Event>& events);
  Eigen::Vector3d at(const TimedPose& a, const TimedPose& b, double t);
  /// Poses taken along the odometry, and along a straight line.
  long odometryShaped() const { return odometry_shaped_; }
  long straight() const { return straight_; }

 private:
  std::shared_ptr<const OdometryTrack> odometry_;
  long odometry_shaped_ = 0;
  long straight_ = 0;
};

/// Adds simulated UWB ranges (the scenario's [uwb] model, its anchors and, when given, NLOS from
/// `map`) to a recorded event stream, at the poses of `reference` (interpolated between them by
/// `path`, by default a PathBetweenPoses over `events`): from tag 0 (unless `simulate_tag0` is
/// false) and from each of the spec's extra tags.
std::vector<loc::Event> augmentWithUwb(const std::vector<loc::Event>& events,
                                       const std::vector<TimedPose>& reference,
                                       const std::vector<uwb::Anchor>& anchors,
                                       const UwbSimSpec& uwb, const loc::OccupancyMap* map,
                                       uint64_t seed, std::vector<RangeTruth>* truth = nullptr,
                                       double max_gap = 2.0, bool simulate_tag0 = true,
                                       PathBetweenPoses* path = nullptr);

struct AugmentRequest {
  std::string rawlog;            ///< recording with scans and odometry
  std::string reference;         ///< reference poses: TUM (.tum) or "time x y phi"
  std::string anchors_csv;       ///< id,x,y,z in the reference frame
  std::string scenario;          ///< optional: take the [uwb] model from this scenario
  std::string map;               ///< optional map for NLOS; "scans" builds one from the scans
  double map_resolution = 0.05;  ///< for a map built from the scans [m]
  double max_gap = 5.0;          ///< no ranges where reference poses are further apart [s]
  uint64_t seed = 1;
  bool allow_bad_time = false;  ///< augment a recording whose timestamps have collapsed
};

/// augmentWithUwb() on files (a recording with ranges of its own keeps them as tag 0 when the
/// scenario adds extra tags: only those are simulated): writes augmented.rawlog, anchors.csv,
/// reference.txt,
/// range_truth.csv, map.gridmap.gz (when NLOS is simulated) and dataset.ini into `out_dir`.
/// Returns the manifest path.
std::string writeAugmented(const AugmentRequest& request, const std::string& out_dir);

/// Writes "t x y phi" rows.
std::string formatTimeXyPhi(const std::vector<TimedPose>& poses);

}  // namespace uwbloc::data
