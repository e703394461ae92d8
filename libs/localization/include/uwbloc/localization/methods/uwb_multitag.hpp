// uwb-multitag: the robot's pose (x, y, heading) from one epoch of ranges of all its tags.
//
// Each tag k sits at l_k on the robot (x forward, y left; its height z_k). A range r_i from tag
// k(i) to anchor a_i is modelled as
//
//   r_i = || (p + R(theta) l_k)_xy , z_k) - a_i || + noise,
//
// and (x, y, theta) minimises the Huber-weighted squared residuals by Gauss-Newton. Start: the
// previous epoch's pose when it is recent; otherwise each tag with three ranges or more is
// multilaterated and the lever arms are fitted to those points in closed form (2D Procrustes);
// with one such tag the heading is started at four headings and the best fit kept. Two tags or
// more observe the heading from one epoch, without motion; one tag alone keeps the previous
// heading (heading_valid false until two tags have been seen).
//
// smooth=true (default) filters the per-epoch fixes with a Kalman filter on
// [x y theta vx vy omega] (white acceleration and angular acceleration). Each fix's covariance
// is (J^T W J)^-1 scaled by the range variance the data shows: the running median of the
// epochs' residual variance sum(r^2) / (n - 3), so no range noise is assumed. A fix whose
// innovation fails the chi-square gate (3 dof) is counted and skipped; after `max_gated` in a
// row the filter restarts on the fix.
#pragma once

#include <optional>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct UwbMultitagParams {
  RangeFrontEndParams front;
  AutoDouble epoch_window;  ///< ranges within this span form one epoch [s]
  double huber = 2.0;       ///< Huber threshold on residual / sigma
  int max_iterations = 15;
  double restart_after = 1.0;  ///< start afresh when the last pose is older than this [s]
  bool smooth = true;          ///< filter the fixes (else: each epoch's fix as it is)
  double accel_psd = 1.0;      ///< white acceleration density [m^2/s^3]
  double yaw_accel_psd = 1.0;  ///< white angular acceleration density [rad^2/s^3]
  double gate = 16.27;         ///< chi-square gate on a fix's innovation (3 dof, 99.9 %)
  int max_gated = 20;          ///< restart the filter after this many gated fixes in a row
  /// Check each one-tag epoch's fix against the robot's reach (fix_continuity.hpp); an epoch of
  /// several tags fits the heading too, and is taken as it is.
  bool continuity = true;
  /// calib, calib_bias: the learning start (range_noise.hpp), from the primary tag's ranges; the
  /// scale and std learnt apply to every tag's.
  RangeLearningParams learning;

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("window", epoch_window,
      "epoch window [s], or auto (one round of ranges from the data's rate)");
    v("huber", huber, "Huber threshold on |residual| / sigma");
    v("iterations", max_iterations, "Gauss-Newton iterations at most");
    v("restart_after", restart_after,
      "start from the closed form when the last pose is older than this [s]");
    v("smooth", smooth, "Kalman filter on the per-epoch fixes (false: raw fixes)");
    v("accel_psd", accel_psd, "smoothing: white acceleration density [m^2/s^3]");
    v("yaw_accel_psd", yaw_accel_psd, "smoothing: white angular acceleration density [rad^2/s^3]");
    v("gate", gate, "smoothing: chi-square gate on a fix's innovation (3 dof)");
    v("max_gated", max_gated, "smoothing: restart after this many gated fixes in a row");
    v("continuity", continuity, kContinuityHelp);
    learning.visit(v);
  }
};

/// The robot pose from one epoch of multi-tag ranges, started at `start` (or the closed form).
/// Exposed for tests. Returns nothing when the ranges cannot fix a pose (fewer than 3, or the
/// solve diverges).
struct MultitagFix {
  Eigen::Vector3d pose = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int tags = 0;             ///< distinct tags in the epoch
  double rms_residual = 0;  ///< [m]
};
std::optional<MultitagFix> solveMultitag(const std::vector<AcceptedRange>& epoch, double sigma,
                                         double huber, int max_iterations,
                                         const std::optional<Eigen::Vector3d>& start);

class UwbMultitag : public EpochUwbEstimator {
 public:
  UwbMultitag(const UwbMultitagParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) override;
  /// The fixes' variance comes from their own residuals (rangeVariance), and the learnt std,
  /// which counts NLOS ranges, would only widen the Huber threshold (simulated office: 0.377 m
  /// with it, 0.313 without).
  bool estimatesOwnNoise() const override { return true; }

 private:
  /// Adds an epoch's residual variance (sum r^2 / (n - 3), with more than 3 ranges) to the window.
  void noteVariance(const MultitagFix& fix, size_t ranges);
  /// The range variance the data shows: the window's median (rangeSigma()^2 until 5 epochs).
  /// A fix's covariance is scaled by it over rangeSigma()^2.
  double rangeVariance();
  /// A one-tag epoch's fix checked for continuity of the robot's position (the tag's point moved
  /// by the lever arm at the held heading); nothing when refused. `replaced`: a position that
  /// leaves ranges out was used.
  std::optional<MultitagFix> continuityChecked(const std::vector<AcceptedRange>& epoch,
                                               const MultitagFix& fix, bool* replaced);
  /// Filters a fix; false when gated.
  bool filter(double t, const MultitagFix& fix, const Eigen::Matrix3d& r);

  UwbMultitagParams params_;
  std::optional<Eigen::Vector3d> last_;
  double last_t_ = -1e300;
  bool heading_seen_ = false;
  WindowMedian variances_{201};  ///< recent epochs' residual variance
  bool filtering_ = false;
  Eigen::Matrix<double, 6, 1> x_ = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 6> p_ = Eigen::Matrix<double, 6, 6>::Identity();
  double t_ = 0.0;
  int gated_in_a_row_ = 0;
};

}  // namespace uwbloc::loc
