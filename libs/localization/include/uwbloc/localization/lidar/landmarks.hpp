// LiDAR landmarks: line segments by split-and-merge, corners where consecutive segments meet,
// the landmark observation model of the PF-IBAS paper's eq. (5) with analytic Jacobians, and a
// landmark map built by nearest-neighbour association with a Mahalanobis gate.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::loc {

struct LineSegment {
  Eigen::Vector2d a, b;  ///< end points in the scan's robot frame
  int points = 0;
};

struct LandmarkExtractionParams {
  double split_dist = 0.05;   ///< split a run where a point is farther than this from the chord [m]
  double gap = 0.3;           ///< consecutive points farther apart start a new run [m]
  int min_points = 6;         ///< shortest segment, in points
  double min_length = 0.3;    ///< shortest segment [m]
  double corner_join = 0.25;  ///< segment ends this close may form a corner [m]
  double corner_min_deg = 50;  ///< corner angle range [deg]
  double corner_max_deg = 130;
  double max_range = 10.0;  ///< ignore returns beyond [m]
};

/// Line segments of a scan (robot frame), by recursive split-and-merge over ordered returns.
std::vector<LineSegment> extractLines(const LaserScan& scan, const LandmarkExtractionParams& p);

/// Corners: intersections of consecutive segments whose ends meet at a clear angle.
std::vector<Eigen::Vector2d> extractCorners(const std::vector<LineSegment>& lines,
                                            const LandmarkExtractionParams& p);

/// Eq. (5): landmark x_m seen from pose x = (x, y, theta): x_L = R(theta)^T (x_m - t).
/// Jacobians with respect to the pose (2x3) and the landmark (2x2) when asked.
Eigen::Vector2d observeLandmarkXy(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark,
                                  Eigen::Matrix<double, 2, 3>* j_pose = nullptr,
                                  Eigen::Matrix2d* j_landmark = nullptr);

/// The same observation as range and bearing: (||x_L||, atan2(x_L.y, x_L.x)).
Eigen::Vector2d observeLandmarkRangeBearing(const Eigen::Vector3d& pose,
                                            const Eigen::Vector2d& landmark,
                                            Eigen::Matrix<double, 2, 3>* j_pose = nullptr,
                                            Eigen::Matrix2d* j_landmark = nullptr);

struct Landmark {
  int id = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  ///< map frame
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  int observations = 0;
};

/// A landmark map grown along a run: each observation (robot frame, covariance R) seen from a
/// pose with covariance P is matched to the nearest landmark under a chi-square gate on the
/// innovation covariance H_x P H_x^T + H_m C H_m^T + R, and fused into it (Kalman update of the
/// landmark alone); an unmatched observation starts a new landmark.
class LandmarkMap {
 public:
  explicit LandmarkMap(double gate = 9.21) : gate_(gate) {}  // 99 %, 2 dof
  /// Returns the id of the landmark the observation was associated with or created as.
  int integrate(const Eigen::Vector3d& pose, const Eigen::Matrix3d& pose_cov,
                const Eigen::Vector2d& observation, const Eigen::Matrix2d& obs_cov);
  const std::vector<Landmark>& landmarks() const { return landmarks_; }
  /// CSV "id,x,y,observations,var_x,var_y".
  std::string toCsv() const;

 private:
  double gate_;
  std::vector<Landmark> landmarks_;
};

}  // namespace uwbloc::loc
