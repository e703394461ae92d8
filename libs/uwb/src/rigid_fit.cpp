#include "uwbloc/uwb/rigid_fit.hpp"

#include <Eigen/Cholesky>
#include <cmath>

namespace uwbloc::uwb {

Pose2 procrustes2d(const std::vector<BodyPoint>& points, const std::vector<double>& weights) {
  Eigen::Vector2d bc = Eigen::Vector2d::Zero(), mc = Eigen::Vector2d::Zero();
  double w_sum = 0.0;
  for (size_t k = 0; k < points.size(); ++k) {
    bc += weights[k] * points[k].on_body;
    mc += weights[k] * points[k].measured;
    w_sum += weights[k];
  }
  bc /= w_sum;
  mc /= w_sum;
  double cos_sum = 0.0, sin_sum = 0.0;
  for (size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector2d a = points[k].on_body - bc, b = points[k].measured - mc;
    cos_sum += weights[k] * a.dot(b);
    sin_sum += weights[k] * (a.x() * b.y() - a.y() * b.x());
  }
  const double theta = std::atan2(sin_sum, cos_sum);
  const Eigen::Vector2d t = mc - rotation(theta) * bc;
  return {t.x(), t.y(), theta};
}

std::optional<RigidFit> fitRigidBody(const std::vector<BodyPoint>& points) {
  if (points.size() < 2) return std::nullopt;
  std::vector<Eigen::Matrix2d> info;
  std::vector<double> weights;
  for (const auto& p : points) {
    const Eigen::LLT<Eigen::Matrix2d> llt(p.covariance);
    if (llt.info() != Eigen::Success || !p.covariance.allFinite()) return std::nullopt;
    info.push_back(llt.solve(Eigen::Matrix2d::Identity()));
    weights.push_back(2.0 / p.covariance.trace());
  }
  RigidFit fit;
  fit.pose = procrustes2d(points, weights);
  Eigen::Matrix3d h;
  for (int it = 0; it < 10; ++it) {
    // e_k = m_k - t - R(theta) b_k; de_k/d(t, theta) = -[I, R'(theta) b_k].
    h.setZero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    const Eigen::Matrix2d r = rotation(fit.pose.z()), dr = rotationDerivative(fit.pose.z());
    for (size_t k = 0; k < points.size(); ++k) {
      Eigen::Matrix<double, 2, 3> j;
      j << Eigen::Matrix2d::Identity(), dr * points[k].on_body;
      const Eigen::Vector2d e = points[k].measured - fit.pose.head<2>() - r * points[k].on_body;
      h += j.transpose() * info[k] * j;
      g += j.transpose() * info[k] * e;
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(h);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive() ||
        ldlt.vectorD().minCoeff() <= 1e-12 * ldlt.vectorD().maxCoeff())
      return std::nullopt;
    const Eigen::Vector3d step = ldlt.solve(g);
    if (!step.allFinite()) return std::nullopt;
    fit.pose += step;
    fit.pose.z() = wrapAngle(fit.pose.z());
    if (step.head<2>().norm() < 1e-9 && std::abs(step.z()) < 1e-9) break;
  }
  fit.covariance = h.ldlt().solve(Eigen::Matrix3d::Identity());
  fit.point_chi2.clear();
  fit.chi2 = 0.0;
  for (size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector2d e = points[k].measured - transformPoint(fit.pose, points[k].on_body);
    fit.point_chi2.push_back(e.dot(info[k] * e));
    fit.chi2 += fit.point_chi2.back();
  }
  if (!fit.pose.allFinite() || !fit.covariance.allFinite()) return std::nullopt;
  return fit;
}

}  // namespace uwbloc::uwb
