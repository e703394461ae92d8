// Scoring of any planar trajectory against a reference, with evo's definitions (Grupp, "evo:
// Python package for the evaluation of odometry and SLAM"): absolute pose error raw and after a
// rigid alignment, relative pose error over a distance or time delta, and heading error.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <string>
#include <vector>

#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/localization/estimator.hpp"

namespace uwbloc::eval {

/// How an estimate is paired with the reference.
struct Association {
  /// true: the reference interpolated at the estimate's time, between samples at most max_diff
  /// apart (what `compare` does); false: the reference sample nearest in time, at most max_diff
  /// away (evo's `--t_max_diff`).
  bool interpolate = true;
  double max_diff = 1.0;  ///< [s]
  /// interpolate: a reference whose median step exceeds this [s] is not interpolated. Between
  /// poses that far apart a straight line is not where the robot was (CARMEN intel's reference
  /// poses are 3.4 s apart, and the chord lies 0.13 m from the odometry's path at the median
  /// interval's widest point): the estimates are interpolated instead, at the reference's own
  /// stamps, between estimates at most max_diff apart (or 1.5 of the reference's median steps,
  /// when longer: estimates at the reference's rate but at other stamps still pair). An
  /// estimator that reports at a high rate is then judged where the reference is known, as one
  /// that reports at the reference's stamps.
  double sparse_step = 0.5;
};

/// The median step between the reference's stamps [s] (0 for fewer than two).
double medianStep(const std::vector<data::TimedPose>& reference);

/// How associatePoses pairs estimates with this reference, in words, after "Errors in metres"
/// (the footer of the run's table, and metrics.json's "pairing").
std::string describePairing(const std::vector<data::TimedPose>& reference,
                            const Association& association);

/// One estimate with the reference at its time.
struct PosePair {
  double t = 0.0;
  Eigen::Vector3d ref = Eigen::Vector3d::Zero();  ///< (x, y, theta)
  Eigen::Vector3d est = Eigen::Vector3d::Zero();
  bool heading = true;  ///< the estimate's heading is valid
};

std::vector<PosePair> associatePoses(const std::vector<loc::PoseEstimate>& estimates,
                                     const std::vector<data::TimedPose>& reference,
                                     const Association& association);

enum class Alignment {
  kNone,       ///< raw errors
  kSe2,        ///< the rigid motion minimising the squared position errors (Umeyama, no scale)
  kSe2Origin,  ///< the rigid motion that puts the first estimate on the first reference pose
};
/// "none", "se2", "se2-origin"; throws std::invalid_argument otherwise.
Alignment parseAlignment(const std::string& text);
std::string toString(Alignment a);

/// The rigid motion T = (x, y, theta) that maps the estimates onto the reference: for kSe2 the
/// minimiser of sum |R p_est + t - p_ref|^2 (Umeyama 1991 without scale, in closed form in 2D);
/// for kSe2Origin ref_0 * est_0^-1; identity for kNone or fewer than 2 pairs (kSe2).
Eigen::Vector3d alignmentTransform(const std::vector<PosePair>& pairs, Alignment a);

/// The estimates moved by T (positions and headings).
std::vector<PosePair> applyAlignment(std::vector<PosePair> pairs, const Eigen::Vector3d& T);

/// evo's statistics of an error series; NaN (n = 0) when it is empty.
struct ErrorStats {
  long n = 0;
  double rmse = NAN, mean = NAN, median = NAN, std = NAN, min = NAN, max = NAN, sse = NAN;
};
ErrorStats errorStats(const std::vector<double>& errors);

/// The pairs as metrics.hpp's error samples (estimate minus reference; the heading error NaN
/// where the pair's heading is not valid).
std::vector<ErrorSample> errorSamples(const std::vector<PosePair>& pairs);

/// Planar position error |p_est - p_ref| of each pair (APE, translation part).
std::vector<double> apeErrors(const std::vector<PosePair>& pairs);

/// Heading error |wrap(theta_est - theta_ref)| [deg] of the pairs whose heading is valid.
std::vector<double> yawErrorsDeg(const std::vector<PosePair>& pairs);

/// RPE's delta: how far apart the two poses of a pair are, along the reference path [m] or in
/// time [s]. Parsed from "1m", "0.5 m", "2s"; a bare number is metres.
struct RpeDelta {
  double value = 1.0;
  bool seconds = false;
};
RpeDelta parseRpeDelta(const std::string& text);
std::string toString(const RpeDelta& d);

struct RpeResult {
  ErrorStats trans;    ///< |translation of E_ij| [m]
  ErrorStats rot_deg;  ///< |rotation of E_ij| [deg], pairs whose both headings are valid
};
/// Relative pose error E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q the reference, P the estimate,
/// over consecutive pairs (i, j): i starts at the first pose, j is the first pose whose reference
/// path length (or time) from i reaches the delta, and the next pair starts at j (evo's
/// "consecutive pairs" mode; evo picks the indices on the estimate's path, uwbloc on the
/// reference's, so that every method is judged on the same pairs). Where an estimate's heading
/// is not valid, the reference heading stands in for it: its RPE is then the drift of the
/// displacement alone.
RpeResult relativePoseError(const std::vector<PosePair>& pairs, const RpeDelta& delta);

/// Everything `evaluate` reports for one trajectory.
struct TrajectoryScore {
  long pairs = 0;
  Eigen::Vector3d alignment = Eigen::Vector3d::Zero();  ///< of the requested alignment
  ErrorStats ape;                                       ///< raw
  ErrorStats ape_aligned;                               ///< after the requested alignment
  ErrorStats yaw_deg;                                   ///< raw heading error
  RpeResult rpe;                                        ///< invariant to a rigid alignment
};
TrajectoryScore scoreTrajectory(const std::vector<PosePair>& pairs, Alignment alignment,
                                const RpeDelta& delta);

}  // namespace uwbloc::eval
