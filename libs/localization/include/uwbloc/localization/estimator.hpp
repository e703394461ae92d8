// One interface for every localisation method: feed events, get timestamped poses.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/localization/params.hpp"
#include "uwbloc/localization/range_mixture.hpp"
#include "uwbloc/uwb/gates.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::nlos {
class Model;
}

namespace uwbloc::loc {

class OccupancyMap;
class LearningCache;

struct PoseEstimate {
  double t = 0.0;
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();  ///< (x, y, theta), map frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  bool heading_valid = true;  ///< false when the method does not observe heading
};

/// What a method decided about one range (methods that judge NLOS record these).
struct RangeDecision {
  double t = 0.0;
  int anchor_id = 0;
  double range = 0.0;
  bool flag_pose = false;     ///< the pose-based test flagged it
  bool flag_raycast = false;  ///< the map ray-cast flagged it
  bool used = false;          ///< it weighted the particles
  /// Under the range mixture with each link's NLOS state tracked: P(NLOS) of this range at the
  /// estimate it was tested against (RangeMixture::nlosPosterior); NaN otherwise.
  double p_nlos = std::numeric_limits<double>::quiet_NaN();
};

/// A range model learnt from the data for one anchor (per link).
struct NoiseEstimate {
  double bias = 0.0;   ///< range bias: measured minus true distance [m]
  double sigma = 0.0;  ///< range std about the bias [m]
  long ranges = 0;     ///< ranges it was estimated from
};

/// A range the front end rejected, with the reason (for the residual plot; the counts are in
/// EstimatorStatistics::rejected).
struct RangeRejection {
  double t = 0.0;
  int anchor_id = 0;
  int tag_id = 0;
  double range = 0.0;
  std::string reason;
};

struct EstimatorStatistics {
  std::vector<RangeDecision> range_decisions;
  std::vector<RangeRejection> range_rejections;  ///< every range the front end rejected
  std::map<std::string, long> rejected;          ///< reason -> count
  std::map<int, std::map<std::string, long>> rejected_by_anchor;  ///< anchor -> reason -> count
  long accepted_ranges = 0;
  long resets = 0;  ///< divergence re-initialisations
  /// Things the method did that are not rejections, by name: PF-IBAS's diversity injections
  /// ("swarm_diversity_injection"), epochs whose NLOS test was suspended ("nlos_test_suspended").
  std::map<std::string, long> events;
  /// Per anchor id: the bias and noise the method estimated (empty: it estimates none).
  std::map<int, NoiseEstimate> estimated_noise;
  /// Per tag id, with two tags or more: the robust std of that tag's range residuals (sigma,
  /// ranges; bias 0), as the graph's learning finds it.
  std::map<int, NoiseEstimate> estimated_tag_noise;
  /// The range std the method ended with, when it estimates one (`sigma=auto`).
  std::optional<double> estimated_range_sigma;
  /// The range scale learnt from the data, when one stood out: z = (1 + s) d + bias.
  std::optional<double> estimated_range_scale;
  /// The LOS / NLOS mixture learnt from the range residuals, when it explains them better than
  /// one Gaussian (range_mixture.hpp).
  std::optional<RangeMixture> estimated_range_mixture;
  /// Under the mixture, the time constant of each link's NLOS state when one was learnt [s]
  /// (nlosStatePriors).
  std::optional<double> estimated_nlos_memory;
  /// A learnt white-acceleration spectral density of the tag's motion [m^2/s^3] (q=auto).
  std::optional<double> estimated_accel_psd;
  /// The factor on the odometry noise learnt at the start (a particle filter's a_scale=auto).
  std::optional<double> estimated_motion_scale;
  /// The learnt path's mean squared speed [m^2/s^2], with the q above (motion=cv).
  std::optional<double> mean_square_speed;
};

/// Counts one rejection by reason (and by anchor when anchor_id >= 0).
void countRejection(EstimatorStatistics& stats, const std::string& reason, int anchor_id = -1);

/// Counts a rejected range and keeps it, with the reason, in stats.range_rejections.
void rejectRange(EstimatorStatistics& stats, const uwb::Range& range, const std::string& reason);

/// What a method may know besides the events: anchors, the start pose (for tracking and dead
/// reckoning, taken from the first ground-truth pose), and the run's seed.
struct EstimatorContext {
  std::vector<uwb::Anchor> anchors;
  std::optional<Eigen::Vector3d> initial_pose;
  double initial_time = 0.0;
  /// The start pose's time, or -infinity without a start pose: a method that integrates from the
  /// start pose skips what was recorded before it.
  double startTime() const {
    return initial_pose ? initial_time : -std::numeric_limits<double>::infinity();
  }
  uint64_t seed = 1;
  std::shared_ptr<const OccupancyMap> map;  ///< the dataset's map, when it has one
  /// The dataset's measured LOS range noise, when its manifest states one: the default of
  /// every method's `sigma` parameter (a spec or config value still wins).
  std::optional<double> range_sigma;
  /// The robot's tags that the manifest lists ([tag] tag_<id>); empty: tag 0 alone.
  std::vector<int> robot_tags;
  /// Resolves a method's `nlos_model=` name to a model. The application loads the file (an
  /// estimator never opens one); empty: a method given nlos_model refuses it.
  std::function<std::shared_ptr<const nlos::Model>(const std::string&)> nlos_models;
  /// Learnt models to share with the other runs given the same cache (range_noise.hpp); none:
  /// the method solves its own learning start (an estimator library keeps no state of its own
  /// between runs).
  std::shared_ptr<LearningCache> learning_cache;
};

class Estimator {
 public:
  virtual ~Estimator() = default;
  /// Consumes one event; may return a pose estimate at that event's time. Never returns NaN:
  /// a non-finite estimate is counted, the method is reset and nothing is returned.
  std::optional<PoseEstimate> process(const Event& event);
  /// Called once at the end of the stream, for methods that buffer (epochs).
  std::optional<PoseEstimate> finish();
  /// The same for batch methods (smoothers), which produce their whole trajectory at the end;
  /// for the others it is finish()'s single estimate, if any.
  std::vector<PoseEstimate> finishAll();

  const std::string& name() const { return name_; }
  const EstimatorStatistics& statistics() const { return stats_; }
  /// Files a method produces besides its trajectory, as (file suffix, contents), e.g. a
  /// landmark map ("landmarks.csv"); the run directory stores them as <method>_<suffix>.
  virtual std::vector<std::pair<std::string, std::string>> artifacts() const { return {}; }
  /// Effective parameters (after defaults and overrides).
  const std::vector<ParamInfo>& parameters() const { return params_; }
  void setIdentity(std::string name, std::vector<ParamInfo> params) {
    name_ = std::move(name);
    params_ = std::move(params);
  }

 protected:
  virtual std::optional<PoseEstimate> doProcess(const Event& event) = 0;
  virtual std::optional<PoseEstimate> doFinish() { return std::nullopt; }
  virtual std::vector<PoseEstimate> doFinishAll() {
    auto e = doFinish();
    return e ? std::vector<PoseEstimate>{*e} : std::vector<PoseEstimate>{};
  }
  /// Forget the state after divergence; the next events re-initialise.
  virtual void reset() {}
  /// doFinish() of a method whose doFinishAll() hands out queued estimates (a learning start):
  /// the newest of them.
  std::optional<PoseEstimate> newestOfFinishAll() {
    auto all = doFinishAll();
    if (all.empty()) return std::nullopt;
    return all.back();
  }

  void countRejection(uwb::RejectReason reason, int anchor_id);
  void countRejection(const std::string& reason, int anchor_id = -1);
  EstimatorStatistics stats_;

 private:
  std::optional<PoseEstimate> guard(std::optional<PoseEstimate> estimate);
  std::string name_;
  std::vector<ParamInfo> params_;
};

}  // namespace uwbloc::loc
