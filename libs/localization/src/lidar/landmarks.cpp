#include "uwbloc/localization/lidar/landmarks.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <limits>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

namespace {

double distanceToChord(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                       const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double n = d.norm();
  if (n < 1e-12) return (p - a).norm();
  return std::abs(d.x() * (p.y() - a.y()) - d.y() * (p.x() - a.x())) / n;
}

void splitRun(const std::vector<Eigen::Vector2d>& pts, size_t lo, size_t hi,
              const LandmarkExtractionParams& p, std::vector<LineSegment>& out) {
  if (hi - lo + 1 < static_cast<size_t>(p.min_points)) return;
  double worst = 0.0;
  size_t at = lo;
  for (size_t i = lo + 1; i < hi; ++i) {
    const double d = distanceToChord(pts[i], pts[lo], pts[hi]);
    if (d > worst) {
      worst = d;
      at = i;
    }
  }
  if (worst > p.split_dist) {
    splitRun(pts, lo, at, p, out);
    splitRun(pts, at, hi, p, out);
    return;
  }
  if ((pts[hi] - pts[lo]).norm() >= p.min_length)
    out.push_back({pts[lo], pts[hi], static_cast<int>(hi - lo + 1)});
}

}  // namespace

std::vector<LineSegment> extractLines(const LaserScan& scan, const LandmarkExtractionParams& p) {
  std::vector<Eigen::Vector2d> pts;
  pts.reserve(scan.ranges.size());
  std::vector<LineSegment> out;
  auto flush = [&] {
    if (!pts.empty()) splitRun(pts, 0, pts.size() - 1, p, out);
    pts.clear();
  };
  // A run of consecutive returns; a ray without one (a skipped index) ends the run.
  size_t next = 0;
  forEachScanEndpoint(scan, 1, std::numeric_limits<double>::min(),
                      std::nextafter(p.max_range, HUGE_VAL),
                      [&](size_t i, const Eigen::Vector2d& q) {
                        if (i != next || (!pts.empty() && (q - pts.back()).norm() > p.gap)) flush();
                        pts.push_back(q);
                        next = i + 1;
                      });
  flush();
  // Merge: adjacent segments that are nearly collinear and touch become one.
  std::vector<LineSegment> merged;
  for (const auto& s : out) {
    if (!merged.empty()) {
      auto& m = merged.back();
      if ((m.b - s.a).norm() < p.gap && distanceToChord(s.b, m.a, m.b) < p.split_dist &&
          distanceToChord(m.a, s.a, s.b) < p.split_dist) {
        m.b = s.b;
        m.points += s.points;
        continue;
      }
    }
    merged.push_back(s);
  }
  return merged;
}

std::vector<Eigen::Vector2d> extractCorners(const std::vector<LineSegment>& lines,
                                            const LandmarkExtractionParams& p) {
  std::vector<Eigen::Vector2d> out;
  for (size_t i = 0; i + 1 < lines.size(); ++i) {
    const auto& l1 = lines[i];
    const auto& l2 = lines[i + 1];
    if ((l1.b - l2.a).norm() > p.corner_join) continue;
    const Eigen::Vector2d d1 = (l1.b - l1.a).normalized(), d2 = (l2.b - l2.a).normalized();
    const double angle = std::acos(std::clamp(std::abs(d1.dot(d2)), 0.0, 1.0)) * 180.0 / M_PI;
    if (angle < std::min(p.corner_min_deg, 180.0 - p.corner_max_deg)) continue;
    // Intersection of the two infinite lines: l1.a + s d1 = l2.a + u d2.
    Eigen::Matrix2d m;
    m << d1, -d2;
    if (std::abs(m.determinant()) < 1e-6) continue;
    const Eigen::Vector2d su = m.inverse() * (l2.a - l1.a);
    out.push_back(l1.a + su(0) * d1);
  }
  return out;
}

Eigen::Vector2d observeLandmarkXy(const Eigen::Vector3d& pose, const Eigen::Vector2d& landmark,
                                  Eigen::Matrix<double, 2, 3>* j_pose,
                                  Eigen::Matrix2d* j_landmark) {
  // Eq. (5): x_L = R(theta)^T (x_m - t).
  const Eigen::Matrix2d rt = rotation(pose.z()).transpose();
  const Eigen::Vector2d z = inverseTransformPoint(pose, landmark);
  if (j_landmark) *j_landmark = rt;
  if (j_pose) {
    // d/dt = -R^T; d/dtheta = dR^T/dtheta d = [-s c; -c -s] d = (z.y, -z.x).
    j_pose->leftCols<2>() = -rt;
    j_pose->col(2) << z.y(), -z.x();
  }
  return z;
}

Eigen::Vector2d observeLandmarkRangeBearing(const Eigen::Vector3d& pose,
                                            const Eigen::Vector2d& landmark,
                                            Eigen::Matrix<double, 2, 3>* j_pose,
                                            Eigen::Matrix2d* j_landmark) {
  Eigen::Matrix<double, 2, 3> jp;
  Eigen::Matrix2d jl;
  const Eigen::Vector2d z = observeLandmarkXy(pose, landmark, &jp, &jl);
  const double r2 = std::max(z.squaredNorm(), 1e-18), r = std::sqrt(r2);
  // d(r, phi)/d(z): [z^T / r; (-z.y, z.x) / r^2].
  Eigen::Matrix2d jz;
  jz << z.x() / r, z.y() / r, -z.y() / r2, z.x() / r2;
  if (j_pose) *j_pose = jz * jp;
  if (j_landmark) *j_landmark = jz * jl;
  return {r, std::atan2(z.y(), z.x())};
}

int LandmarkMap::integrate(const Eigen::Vector3d& pose, const Eigen::Matrix3d& pose_cov,
                           const Eigen::Vector2d& observation, const Eigen::Matrix2d& obs_cov) {
  // Nearest neighbour by Mahalanobis distance among the landmarks inside the chi-square gate.
  // For landmark m the observation's noise is the observation's own plus the pose's, seen
  // through the pose Jacobian: R_m = H_x P H_x^T + R, and S = H_m C H_m^T + R_m.
  const uwb::ChiSquareGate gate(gate_);
  int best = -1;
  kalman::Innovation<2> best_inn;
  Eigen::Matrix2d best_hm, best_r;
  for (size_t i = 0; i < landmarks_.size(); ++i) {
    const auto& lm = landmarks_[i];
    Eigen::Matrix<double, 2, 3> hx;
    Eigen::Matrix2d hm;
    const Eigen::Vector2d predicted = observeLandmarkXy(pose, lm.position, &hx, &hm);
    const Eigen::Matrix2d r = hx * pose_cov * hx.transpose() + obs_cov;
    const auto inn = kalman::innovate<2, 2>(lm.covariance, observation - predicted, hm, r);
    if (kalman::inGate(inn, gate) && (best < 0 || inn.d2 < best_inn.d2)) {
      best = static_cast<int>(i);
      best_inn = inn;
      best_hm = hm;
      best_r = r;
    }
  }
  if (best < 0) {
    // New landmark: x_m = t + R z, covariance from the pose and the observation.
    const Eigen::Matrix2d r = rotation(pose.z());
    Landmark lm;
    lm.id = static_cast<int>(landmarks_.size());
    lm.position = transformPoint(pose, observation);
    // d/dtheta of R(theta) z = R(theta + pi/2) z.
    Eigen::Matrix<double, 2, 3> g;
    g.leftCols<2>().setIdentity();
    g.col(2) = rotation(pose.z() + M_PI_2) * observation;
    lm.covariance = g * pose_cov * g.transpose() + r * obs_cov * r.transpose();
    lm.observations = 1;
    landmarks_.push_back(lm);
    return lm.id;
  }
  auto& lm = landmarks_[static_cast<size_t>(best)];
  // Kalman update of the landmark (the shared Joseph-form steps (4)-(6)).
  Eigen::Vector2d position = lm.position;
  kalman::josephUpdate<2, 2>(position, lm.covariance, best_inn, best_hm, best_r);
  lm.position = position;
  ++lm.observations;
  return lm.id;
}

std::string LandmarkMap::toCsv() const {
  std::string out = "id,x,y,observations,var_x,var_y\n";
  char buf[160];
  for (const auto& lm : landmarks_) {
    std::snprintf(buf, sizeof buf, "%d,%.4f,%.4f,%d,%.6f,%.6f\n", lm.id, lm.position.x(),
                  lm.position.y(), lm.observations, lm.covariance(0, 0), lm.covariance(1, 1));
    out += buf;
  }
  return out;
}

}  // namespace uwbloc::loc
