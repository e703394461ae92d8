// Continuity of per-epoch fixes. Among three anchors one wrong range can fit the mirror image of
// the true position exactly (the MRPT demo's beacon 1 does so for tens of seconds), so no
// residual can tell; only the motion can. A fix the tag cannot have reached since the last kept
// one (at the fastest plausible speed, with both fixes' uncertainty) is in doubt, and the reachable
// position that the most of the epoch's ranges fit is used instead, leaving the others out: fault
// exclusion by continuity. The kept fixes also feed a constant-velocity track (a Kalman filter
// driven by white acceleration, its density the data's), and a fix must pass its gate too: at a
// slow robot's pace the speed bound alone reaches metres around the last fix, far enough for a
// wrong fix near the line of the two good anchors, where the mirror and the truth meet and the
// good pair's intersection is known only along that line.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "uwbloc/uwb/multilateration.hpp"

namespace uwbloc::loc {

struct FixContinuityParams {
  double max_speed = 2.0;   ///< fastest plausible tag speed [m/s]
  double floor = 0.3;       ///< distance always reachable, and a range's fit tolerance [m]
  int max_unreachable = 5;  ///< epochs in a row with nothing reachable before a restart
  /// The track's white acceleration density [m^2/s^3]; the range front end sets twice the
  /// learnt path's (EpochUwbEstimator::learn).
  double accel_psd = 0.33;
  double velocity_span = 3.0;  ///< a gap [s] after which the track forgets its velocity
  double gate = 13.8;          ///< the track's chi-square gate (2 dof, 0.999)
  bool track = true;           ///< false: the speed bound alone, from the last kept position
  /// Every range, not only those left out, must agree with the track's prediction for a fix to
  /// be taken as it is (a solver started from the last pose, whose fix a wrong range pulls only
  /// part of the way: uwb-multitag).
  bool every_range = false;
};

/// Why a fix was kept, changed or refused.
enum class Continuity {
  kAsIs,         ///< the fix was reachable (or the first)
  kExcluded,     ///< replaced by a reachable position that leaves some ranges out
  kUnreachable,  ///< refused: nothing the ranges allow is reachable
  kRestart,      ///< taken as it is after max_unreachable refusals in a row
  kTwoRanges,    ///< two ranges only: the track follows the intersection it predicts
};

const char* toString(Continuity c);

class FixContinuity {
 public:
  using Solver = std::function<uwb::Fix(const std::vector<uwb::PlanarRange>&)>;
  struct Checked {
    std::optional<uwb::Fix> fix;  ///< the fix to use; none when refused
    Continuity outcome = Continuity::kAsIs;
    std::vector<int> left_out;  ///< indices into the ranges that the used fix leaves out
  };

  explicit FixContinuity(const FixContinuityParams& params = {}) : params_(params) {}

  /// A known position at time t (the start pose's tag); the first fix is then checked too.
  void seed(double t, const Eigen::Vector2d& position);

  /// Sets every_range.
  void checkEveryRange();

  /// A track with the same parameters (as learnt so far) and no history: another tag's.
  FixContinuity fresh() const { return FixContinuity(params_); }

  /// The track's white acceleration density, as learnt from the data.
  void setAccelPsd(double q);

  /// A speed the data showed (the learnt path's); only raises the one in force.
  void raiseMaxSpeed(double v);

  /// The track predicted to t: position and velocity, and the velocity's covariance at the last
  /// kept fix (without the prediction's white acceleration, which the learnt density sets for the
  /// path's sharpest turns: on a square driven at 3 m/s it doubles the velocity's std, and
  /// deskewRanges would keep a third of the skew, rmse 0.238 against 0.149 m).
  struct Motion {
    Eigen::Vector2d position;
    Eigen::Vector2d velocity;
    Eigen::Matrix2d velocity_cov;
  };
  /// The track's motion at t; nothing while it has no velocity (fewer than two kept fixes, or
  /// the last one over velocity_span before t) or one faster than max_speed (noisy fixes far
  /// from clustered anchors, Hanyang's at 37 m, swing it to 9-16 m/s).
  std::optional<Motion> motion(double t) const;

  /// `fix` (status ok) from `ranges` at time t. When it is not reachable from the last kept
  /// position, each pair of ranges' circle intersections that is reachable and fits all the
  /// ranges but one at most (within max(3 sigma, floor): one fault at a time) is a candidate; the
  /// one that fits the most, then the nearest, is re-solved by `solve` over the ranges it fits
  /// (three or more) or kept as it is (two).
  ///
  /// `offset` moves the ranges' point (a tag) to the point whose continuity is checked and kept
  /// (the robot, with the lever arm rotated by a known heading: -R(theta) l); the fix returned is
  /// the ranges' point.
  Checked check(double t, const uwb::Fix& fix, const std::vector<uwb::PlanarRange>& ranges,
                const Solver& solve, const Eigen::Vector2d& offset = Eigen::Vector2d::Zero());

  /// An epoch of two ranges, which no solver resolves alone: while the track has a velocity, the
  /// intersection of their circles nearest the predicted position, when reachable (outcome
  /// kTwoRanges), else nothing (kUnreachable, not counted towards a restart).
  Checked checkTwo(double t, const std::vector<uwb::PlanarRange>& ranges,
                   const Eigen::Vector2d& offset = Eigen::Vector2d::Zero());

 private:
  /// Within floor + max_speed dt + 3 (the fix's largest std, with `own_std`, + the last kept
  /// one's) of the last kept position and, once the track has a velocity, inside its gate (the
  /// predicted covariance + (floor / 3)^2, + the fix's own with `own_std`). A candidate is judged
  /// without its own std: a pair's intersection near the line through its anchors has a large
  /// one, and would reach anywhere.
  bool reachable(double t, const uwb::Fix& fix, bool own_std, const Eigen::Vector2d& offset) const;
  void keep(double t, const uwb::Fix& fix, const Eigen::Vector2d& offset);
  /// A candidate position as a fix from the ranges it fits (`uwb::fixAt`); two whose circles only
  /// touch or miss give the point on the line between their anchors, uncertain across it.
  uwb::Fix candidateAt(const std::vector<uwb::PlanarRange>& ranges, const Eigen::Vector2d& p) const;
  /// Whether the ranges of the anchors left out at the last kept epoch (every range, with
  /// every_range) agree with the track's prediction again (within 3 sigma: range, prediction and
  /// floor / 3): a fault persists, and a range that is still recovering from one would pull a
  /// fix that the gate lets in.
  bool doubtedRangesAgree(double t, const std::vector<uwb::PlanarRange>& ranges,
                          const Eigen::Vector2d& offset) const;
  /// The track (position, velocity) and its covariance predicted to t.
  void predict(double t, Eigen::Vector4d& x, Eigen::Matrix4d& P) const;
  /// Where the tag is expected at t: the last kept position, or the track's prediction.
  Eigen::Vector2d predicted(double t) const;
  /// The best reachable candidate position, with the indices of the ranges it fits.
  struct Candidate {
    uwb::Fix fix;
    std::vector<int> in;
  };
  std::optional<Candidate> bestReachable(double t, const std::vector<uwb::PlanarRange>& ranges,
                                         const Solver& solve, const Eigen::Vector2d& offset) const;

  FixContinuityParams params_;
  std::optional<Eigen::Vector2d> last_;
  double last_t_ = 0.0;
  double last_std_ = 0.0;  ///< the last kept fix's largest std [m]
  // The constant-velocity track of the kept fixes: x = (position, velocity); with a velocity once
  // two fixes have been kept within velocity_span of each other.
  Eigen::Vector4d track_ = Eigen::Vector4d::Zero();
  Eigen::Matrix4d track_cov_ = Eigen::Matrix4d::Identity();
  bool velocity_ = false;
  std::vector<Eigen::Vector2d> doubted_;  ///< anchors left out at the last kept epoch
  int unreachable_ = 0;
};

}  // namespace uwbloc::loc
