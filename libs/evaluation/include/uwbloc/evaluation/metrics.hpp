// Association of estimates with ground truth, and the error metrics.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/localization/estimator.hpp"

namespace uwbloc::eval {

using data::interpolateGroundTruth;

struct ErrorSample {
  double t = 0.0;
  double ex = 0.0, ey = 0.0;  ///< estimate minus truth [m]
  double e2d = 0.0;           ///< planar error [m]
  /// Heading error, estimate minus truth, wrapped to (-pi, pi] [rad]; NaN when the estimate's
  /// heading is not valid (a method that has not observed it yet).
  double eyaw = 0.0;
};

/// One error sample per estimate that has ground truth at its time.
std::vector<ErrorSample> associate(const std::vector<loc::PoseEstimate>& estimates,
                                   const std::vector<data::TimedPose>& gt, double max_gap = 1.0);

/// Error metrics are NaN when no estimate could be associated with the ground truth.
struct Metrics {
  long steps = 0;         ///< estimates produced
  long associated = 0;    ///< estimates with ground truth
  double coverage = 0.0;  ///< fraction of ground-truth samples with an estimate within tolerance
  double rmse_x = 0.0, rmse_y = 0.0;
  double rmse_2d = 0.0;  ///< sqrt(rmse_x^2 + rmse_y^2), the PF-IBAS paper's RMSE_z
  double mae_2d = 0.0, median_2d = 0.0, p95_2d = 0.0, max_2d = 0.0;
  double final_2d = 0.0;  ///< error of the last scored estimate: the drift of odometry-like methods
  /// Heading error [deg] over the estimates with a valid heading: RMSE, median and 95th
  /// percentile of |error|. NaN when the reference has no heading (manifest:
  /// reference_heading = false) or no such estimate was associated.
  double rmse_yaw_deg = NAN, median_yaw_deg = NAN, p95_yaw_deg = NAN;
  std::vector<std::pair<double, double>> cdf;  ///< (error [m], fraction <= error), 21 points
  /// 2D RMSE after the rigid SE(2) alignment that minimises it (Umeyama, no scale): the error
  /// that a frame offset does not explain. NaN when nothing was associated.
  double rmse_2d_aligned = NAN;
  /// Relative pose error over consecutive kRpeDeltaMetres stretches of the reference path
  /// (trajectory_eval.hpp): RMSE of its translation [m] and of its rotation [deg] (the latter
  /// over estimates with a valid heading). NaN when the path is shorter than one stretch.
  double rpe_trans_rmse = NAN, rpe_rot_rmse_deg = NAN;
  std::string alignment = "se2";  ///< of rmse_2d_aligned (`evaluate --align`)
  std::string rpe_delta = "1m";   ///< the RPE stretch (`evaluate --delta`)
};

/// The RPE stretch of `compare` [m of reference path].
inline constexpr double kRpeDeltaMetres = 1.0;

/// Metrics of the errors; `coverage_tolerance` [s] is how near an estimate must be to a
/// ground-truth sample to cover it.
Metrics computeMetrics(const std::vector<ErrorSample>& errors,
                       const std::vector<loc::PoseEstimate>& estimates,
                       const std::vector<data::TimedPose>& gt, double coverage_tolerance = 1.0,
                       bool reference_heading = true);

/// Quantile q in [0, 1] by linear interpolation of the sorted values.
double quantile(std::vector<double> values, double q);

}  // namespace uwbloc::eval
