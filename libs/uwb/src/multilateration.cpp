#include "uwbloc/uwb/multilateration.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <utility>

namespace uwbloc::uwb {

const char* toString(FixStatus s) {
  constexpr std::pair<FixStatus, const char*> kNames[] = {
      {FixStatus::kOk, "ok"},
      {FixStatus::kTooFewAnchors, "too_few_anchors"},
      {FixStatus::kDegenerate, "degenerate_geometry"},
      {FixStatus::kNoConvergence, "no_convergence"},
  };
  for (const auto& [status, name] : kNames)
    if (status == s) return name;
  return "unknown";
}

namespace {

// Anchors whose centred coordinates have a tiny second singular value relative to the first
// (collinear) or a tiny spread (coincident) admit mirror solutions: refuse them.
bool degenerateGeometry(const std::vector<PlanarRange>& ranges) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& r : ranges) mean += r.anchor;
  mean /= static_cast<double>(ranges.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& r : ranges) scatter += (r.anchor - mean) * (r.anchor - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(scatter);
  const double lmax = es.eigenvalues()(1), lmin = es.eigenvalues()(0);
  return lmax < 1e-12 || lmin < 1e-6 * lmax;
}

double residualNorm(const std::vector<PlanarRange>& ranges, const Eigen::Vector2d& p) {
  double s = 0.0;
  for (const auto& r : ranges) {
    const double e = r.range - (p - r.anchor).norm();
    s += e * e;
  }
  return std::sqrt(s);
}

std::optional<Fix> precheck(const std::vector<PlanarRange>& ranges) {
  Fix fix;
  if (ranges.size() < 3) {
    fix.status = FixStatus::kTooFewAnchors;
    return fix;
  }
  if (degenerateGeometry(ranges)) {
    fix.status = FixStatus::kDegenerate;
    return fix;
  }
  return std::nullopt;
}

}  // namespace

Fix fixAt(const std::vector<PlanarRange>& ranges, const Eigen::Vector2d& p, int iterations) {
  Fix fix;
  fix.position = p;
  fix.iterations = iterations;
  fix.residual_norm = residualNorm(ranges, p);
  if (!p.allFinite()) {
    fix.status = FixStatus::kNoConvergence;
    return fix;
  }
  const auto cov = crlb2d(ranges, p);
  if (!cov) {
    fix.status = FixStatus::kDegenerate;
    return fix;
  }
  fix.covariance = *cov;
  fix.status = FixStatus::kOk;
  return fix;
}

std::optional<Eigen::Matrix2d> crlb2d(const std::vector<PlanarRange>& ranges,
                                      const Eigen::Vector2d& position) {
  // Fisher information J = sum_i u_i u_i^T / sigma_i^2, u_i the unit vector anchor -> tag.
  Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
  for (const auto& r : ranges) {
    const Eigen::Vector2d d = position - r.anchor;
    const double n = d.norm();
    if (n < 1e-9) continue;
    const Eigen::Vector2d u = d / n;
    info += u * u.transpose() / (r.sigma * r.sigma);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(info);
  if (es.eigenvalues()(0) <= 1e-9 * std::max(1.0, es.eigenvalues()(1))) return std::nullopt;
  return info.inverse();
}

Fix solveLinearLS(const std::vector<PlanarRange>& ranges) {
  if (auto bad = precheck(ranges)) return *bad;
  // Subtracting circle 0 from circle i:
  //   2 (a_i - a_0)^T p = r_0^2 - r_i^2 + |a_i|^2 - |a_0|^2      i = 1..N-1
  const auto n = static_cast<Eigen::Index>(ranges.size()) - 1;
  Eigen::MatrixXd a(n, 2);
  Eigen::VectorXd b(n);
  const auto& r0 = ranges.front();
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto& ri = ranges[static_cast<size_t>(i + 1)];
    a.row(i) = 2.0 * (ri.anchor - r0.anchor).transpose();
    b(i) = r0.range * r0.range - ri.range * ri.range + ri.anchor.squaredNorm() -
           r0.anchor.squaredNorm();
  }
  const Eigen::Vector2d p = a.colPivHouseholderQr().solve(b);
  return fixAt(ranges, p, 1);
}

Fix solveGaussNewton(const std::vector<PlanarRange>& ranges,
                     const std::optional<Eigen::Vector2d>& initial,
                     const GaussNewtonParams& params) {
  if (auto bad = precheck(ranges)) return *bad;
  Eigen::Vector2d p;
  if (initial) {
    p = *initial;
  } else {
    const Fix ls = solveLinearLS(ranges);
    if (!ls.ok()) return ls;
    p = ls.position;
  }
  int it = 0;
  for (; it < params.max_iterations; ++it) {
    // Normal equations of min sum_i (r_i - ||p - a_i||)^2 / sigma_i^2.
    Eigen::Matrix2d jtj = Eigen::Matrix2d::Zero();
    Eigen::Vector2d jte = Eigen::Vector2d::Zero();
    for (const auto& r : ranges) {
      const Eigen::Vector2d d = p - r.anchor;
      const double h = std::max(d.norm(), 1e-9);
      const Eigen::Vector2d u = d / h;
      const double w = 1.0 / (r.sigma * r.sigma);
      jtj += w * u * u.transpose();
      jte += w * u * (r.range - h);
    }
    const Eigen::Vector2d step = jtj.ldlt().solve(jte);
    if (!step.allFinite()) break;
    p += step;
    if (step.norm() < params.tolerance) {
      ++it;
      return fixAt(ranges, p, it);
    }
  }
  Fix fix = fixAt(ranges, p, it);
  // Slow final convergence is still a usable fix; only a blown-up iterate is a failure.
  if (!p.allFinite()) fix.status = FixStatus::kNoConvergence;
  return fix;
}

Fix solveChan(const std::vector<PlanarRange>& ranges) {
  if (auto bad = precheck(ranges)) return *bad;
  // Move the origin well outside the anchor hull so that the target's coordinates are far from
  // zero; step 2 recovers |x|, |y| and takes their signs from step 1.
  Eigen::Vector2d lo = ranges.front().anchor, hi = lo;
  double rmax = 0.0;
  for (const auto& r : ranges) {
    lo = lo.cwiseMin(r.anchor);
    hi = hi.cwiseMax(r.anchor);
    rmax = std::max(rmax, r.range);
  }
  const double span = (hi - lo).maxCoeff() + rmax + 1.0;
  const Eigen::Vector2d origin = lo - Eigen::Vector2d::Constant(span);

  const auto m = static_cast<Eigen::Index>(ranges.size());
  // Step 1: r_i^2 - K_i = -2 x_i x - 2 y_i y + R, with K_i = x_i^2 + y_i^2, R = x^2 + y^2.
  Eigen::MatrixXd ga(m, 3);
  Eigen::VectorXd h(m);
  Eigen::VectorXd q(m);  // range variances
  for (Eigen::Index i = 0; i < m; ++i) {
    const auto& r = ranges[static_cast<size_t>(i)];
    const Eigen::Vector2d a = r.anchor - origin;
    ga.row(i) << -2.0 * a.x(), -2.0 * a.y(), 1.0;
    h(i) = r.range * r.range - a.squaredNorm();
    q(i) = r.sigma * r.sigma;
  }
  // Weight Psi = B Q B with B = diag(2 r_i): the error of r_i^2 is about 2 r_i e_i.
  Eigen::VectorXd psi_inv(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const double b = 2.0 * std::max(ranges[static_cast<size_t>(i)].range, 1e-3);
    psi_inv(i) = 1.0 / (b * b * q(i));
  }
  const Eigen::MatrixXd gtw = ga.transpose() * psi_inv.asDiagonal();
  const Eigen::Matrix3d na = gtw * ga;
  const Eigen::Vector3d za = na.ldlt().solve(gtw * h);
  if (!za.allFinite()) return fixAt(ranges, Eigen::Vector2d::Constant(NAN), 1);
  const Eigen::Matrix3d cov_a = na.inverse();

  // Step 2: h' = [x^2, y^2, R] = G' [x^2; y^2] with G' = [1 0; 0 1; 1 1],
  // weight Psi' = 4 B' cov_a B', B' = diag(x, y, 1/2).
  Eigen::Matrix<double, 3, 2> g2;
  g2 << 1, 0, 0, 1, 1, 1;
  const Eigen::Vector3d h2(za(0) * za(0), za(1) * za(1), za(2));
  const Eigen::DiagonalMatrix<double, 3> b2(za(0), za(1), 0.5);
  const Eigen::Matrix3d psi2 = 4.0 * (b2 * cov_a * b2);
  const Eigen::Matrix3d psi2_inv = psi2.inverse();
  Eigen::Vector2d p;
  if (psi2_inv.allFinite()) {
    const Eigen::Matrix2d n2 = g2.transpose() * psi2_inv * g2;
    const Eigen::Vector2d z2 = n2.ldlt().solve(g2.transpose() * psi2_inv * h2);
    p << std::copysign(std::sqrt(std::abs(z2(0))), za(0)),
        std::copysign(std::sqrt(std::abs(z2(1))), za(1));
    if (!p.allFinite()) p = za.head<2>();
  } else {
    p = za.head<2>();  // noise-free input: step 1 is already exact
  }
  return fixAt(ranges, p + origin, 2);
}

std::vector<Eigen::Vector2d> circleIntersections(const PlanarRange& a, const PlanarRange& b) {
  const Eigen::Vector2d d12 = b.anchor - a.anchor;
  const double dist = d12.norm();
  if (!(dist > 1e-6)) return {};
  const Eigen::Vector2d ex = d12 / dist;
  const Eigen::Vector2d ey(-ex.y(), ex.x());
  // Along the centre line: x = (r1^2 - r2^2 + D^2) / 2D; across it: y = +-sqrt(r1^2 - x^2).
  const double x = (a.range * a.range - b.range * b.range + dist * dist) / (2.0 * dist);
  const double y2 = a.range * a.range - x * x;
  if (!(y2 > 0.0)) return {a.anchor + x * ex};
  const double y = std::sqrt(y2);
  return {a.anchor + x * ex + y * ey, a.anchor + x * ex - y * ey};
}

Fix solveThreeAnchors(const std::vector<PlanarRange>& ranges) {
  if (ranges.size() != 3) {
    Fix fix;
    fix.status = ranges.size() < 3 ? FixStatus::kTooFewAnchors : FixStatus::kDegenerate;
    if (ranges.size() > 3) {
      // Use the first three; callers that have more should use a least-squares solver.
      return solveThreeAnchors({ranges[0], ranges[1], ranges[2]});
    }
    return fix;
  }
  if (auto bad = precheck(ranges)) return *bad;
  const auto points = circleIntersections(ranges[0], ranges[1]);
  if (points.empty()) {
    Fix fix;
    fix.status = FixStatus::kDegenerate;
    return fix;
  }
  const auto& c3 = ranges[2];
  const Eigen::Vector2d& pa = points.front();
  const Eigen::Vector2d& pb = points.back();
  const double ea = std::abs((pa - c3.anchor).norm() - c3.range);
  const double eb = std::abs((pb - c3.anchor).norm() - c3.range);
  return fixAt(ranges, ea <= eb ? pa : pb, 1);
}

}  // namespace uwbloc::uwb
