// Point-based Gaussian filters of the H∞ cubature paper (adaptive-hinf-ckf-uwb-ins.txt) and its
// comparison filters. That paper's equations were lost in extraction, so the standard forms are
// used and cited here:
//
// CKF: Arasaratnam & Haykin, "Cubature Kalman filters", IEEE TAC 54(6), 2009, §IV-V. The
//   third-degree spherical-radial rule: 2n points x ± sqrt(n) L e_i (L L^T = P), each of weight
//   1/(2n). A measurement update propagates the points through h:
//     z = Σ w h(X_i),  P_zz = Σ w (Z_i - z)(Z_i - z)^T + R,  P_xz = Σ w (X_i - x)(Z_i - z)^T,
//     K = P_xz P_zz^-1,  x <- x + K (z_meas - z),  P <- P - K P_zz K^T.
//   Its time update does the same through f, adding Q.
//
// H∞ CKF: the cubature H∞ filter in the form of Chandra, Gu & Postlethwaite ("Square root
//   cubature information filter", IEEE Sensors J. 13(2), 2013) and most UWB/INS papers: the
//   statistically linearised H = (P^-1 P_xz)^T put into the H∞ Riccati update (Simon, "Optimal
//   State Estimation", 2006, §11.3):
//     P <- (P^-1 + H^T R^-1 H - γ^-2 L^T L)^-1,
//   where L selects the estimated quantity (Simon's eq. 11.89 form; the filters here bound the
//   position, L = [I 0], since a range update applied at the range rate to the unobserved
//   velocity with L = I inflated it at every range and diverged on every recording),
//   the state updated as the CKF's. The bound γ must keep the bracket positive definite: it
//   caps the variance of L x in every direction below γ^2, and the smaller γ, the more the
//   update inflates P towards that cap (robustness against unmodelled errors, at the cost of
//   variance); γ → ∞ is the CKF. γ is given as a ratio (> 1) to the smallest feasible γ,
//   sqrt(λ_max(L P_ckf L^T)), so that one setting means the same on every data set: an absolute
//   γ sat near the variance of Hanyang's poorly observed direction and diverged (γ 0.5-5 m:
//   4.6-14.2 m on LOS A1, against the CKF's 0.98 m). Where
//   rounding still leaves the bracket indefinite, the update is the CKF's and it is counted.
//
// SRUKF: van der Merwe & Wan, "The square-root unscented Kalman filter for state and parameter
//   estimation", ICASSP 2001, Algorithm 3.1: the scaled unscented points (α, β, κ), the square
//   root S (P = S S^T) propagated by a QR decomposition and rank-one Cholesky updates; a
//   downdate (the measurement update, and a negative zeroth weight) can lose definiteness by
//   rounding, and then S is recomputed from S S^T - u u^T with its eigenvalues floored.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <cmath>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc::kalman {

/// A lower-triangular L with L L^T = P; when rounding has made P indefinite, its eigenvalues are
/// floored at zero first.
template <int N>
Mat<N, N> lowerSquareRoot(const Mat<N, N>& p) {
  const Mat<N, N> sym = 0.5 * (p + p.transpose());
  Eigen::LLT<Mat<N, N>> llt(sym);
  if (llt.info() == Eigen::Success) return llt.matrixL();
  Eigen::SelfAdjointEigenSolver<Mat<N, N>> eig(sym);
  const Mat<N, N> v = eig.eigenvectors() * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
  // A square root that is not triangular is still one (S S^T = P); make it triangular by QR.
  Eigen::HouseholderQR<Mat<N, N>> qr(v.transpose());
  Mat<N, N> r = qr.matrixQR().template triangularView<Eigen::Upper>();
  return r.transpose();
}

/// A weighted point set: the points (columns) and their mean and covariance weights.
template <int N, int K>
struct PointSet {
  Mat<N, K> x;
  Vec<K> wm;
  Vec<K> wc;
};

/// The cubature points of N(x, P): 2n points x ± sqrt(n) L e_i, weights 1/(2n).
template <int N>
PointSet<N, 2 * N> cubaturePoints(const Vec<N>& x, const Mat<N, N>& p) {
  const Mat<N, N> l = std::sqrt(static_cast<double>(N)) * lowerSquareRoot<N>(p);
  PointSet<N, 2 * N> s;
  for (int i = 0; i < N; ++i) {
    s.x.col(i) = x + l.col(i);
    s.x.col(N + i) = x - l.col(i);
  }
  s.wm.setConstant(1.0 / (2 * N));
  s.wc = s.wm;
  return s;
}

/// The scaled unscented points of N(x, S S^T): x, x ± sqrt(n + λ) S e_i, λ = α^2 (n + κ) - n,
/// weights wm_0 = λ / (n + λ), wc_0 = wm_0 + 1 - α^2 + β, the others 1 / (2 (n + λ)).
template <int N>
PointSet<N, 2 * N + 1> unscentedPoints(const Vec<N>& x, const Mat<N, N>& s, double alpha,
                                       double beta, double kappa) {
  const double lambda = alpha * alpha * (N + kappa) - N;
  const double c = std::sqrt(N + lambda);
  PointSet<N, 2 * N + 1> set;
  set.x.col(0) = x;
  for (int i = 0; i < N; ++i) {
    set.x.col(1 + i) = x + c * s.col(i);
    set.x.col(1 + N + i) = x - c * s.col(i);
  }
  set.wm.setConstant(0.5 / (N + lambda));
  set.wc = set.wm;
  set.wm(0) = lambda / (N + lambda);
  set.wc(0) = set.wm(0) + 1.0 - alpha * alpha + beta;
  return set;
}

/// The moments of a point set propagated through h: the predicted measurement, its covariance
/// (without R) and the state-measurement cross-covariance.
template <int N, int M, int K>
struct PointMoments {
  Vec<M> z;
  Mat<M, M> pzz;
  Mat<N, M> pxz;
  Mat<M, K> zs;  ///< the propagated points (the square-root filter reuses them)
};

template <int N, int M, int K, class H>
PointMoments<N, M, K> propagate(const PointSet<N, K>& set, const Vec<N>& x, H&& h) {
  PointMoments<N, M, K> m;
  for (int i = 0; i < K; ++i) m.zs.col(i) = h(Vec<N>(set.x.col(i)));
  m.z = m.zs * set.wm;
  m.pzz.setZero();
  m.pxz.setZero();
  for (int i = 0; i < K; ++i) {
    const Vec<M> dz = m.zs.col(i) - m.z;
    m.pzz += set.wc(i) * dz * dz.transpose();
    m.pxz += set.wc(i) * (set.x.col(i) - x) * dz.transpose();
  }
  return m;
}

/// The CKF's time update through f: x <- Σ w f(X_i), P <- Σ w (f(X_i) - x)(...)^T + Q.
template <int N, class F>
void cubaturePredict(Vec<N>& x, Mat<N, N>& p, F&& f, const Mat<N, N>& q) {
  const auto set = cubaturePoints<N>(x, p);
  const auto m = propagate<N, N>(set, x, f);
  x = m.z;
  p = m.pzz + q;
}

/// The CKF's measurement update with innovation y = z_meas - m.z and noise R.
template <int N, int M, int K>
void cubatureUpdate(Vec<N>& x, Mat<N, N>& p, const PointMoments<N, M, K>& m, const Vec<M>& y,
                    const Mat<M, M>& r) {
  const Mat<M, M> pzz = m.pzz + r;
  const Mat<N, M> k = m.pxz * pzz.inverse();
  x += k * y;
  p -= k * pzz * k.transpose();
  p = 0.5 * (p + p.transpose());
}

/// The H∞ CKF's measurement update (see the header) with bound γ on the estimate L x (`ltl` is
/// L^T L: the identity bounds every state, a selection only the states that matter), γ given as
/// `ratio` (> 1) times its smallest feasible value, sqrt(λ_max(L P_ckf L^T)) with P_ckf =
/// (P^-1 + H^T R^-1 H)^-1: the state as cubatureUpdate's, the covariance from the H∞ Riccati
/// form. Returns the γ used; where rounding leaves the bracket indefinite the covariance is the
/// CKF's and 0 is returned (the caller counts it).
template <int N, int M, int K>
double hinfCubatureUpdate(Vec<N>& x, Mat<N, N>& p, const PointMoments<N, M, K>& m, const Vec<M>& y,
                          const Mat<M, M>& r, double ratio, const Mat<N, N>& ltl) {
  // P and the information are symmetric positive definite: inverted through their Cholesky
  // factors (LU where rounding has made one indefinite), and only the largest eigenvalue is
  // needed, without eigenvectors.
  auto spdInverse = [](const Mat<N, N>& a) -> Mat<N, N> {
    Eigen::LLT<Mat<N, N>> llt(a);
    return llt.info() == Eigen::Success ? Mat<N, N>(llt.solve(Mat<N, N>::Identity()))
                                        : Mat<N, N>(a.inverse());
  };
  const Mat<N, N> p_inv = spdInverse(p);
  const Mat<M, N> h = (p_inv * m.pxz).transpose();  // statistical linearisation
  const Mat<N, N> info = p_inv + h.transpose() * r.inverse() * h;
  const Mat<N, N> p_ckf = spdInverse(info);
  const Eigen::SelfAdjointEigenSolver<Mat<N, N>> eig(
      0.5 * (ltl * p_ckf * ltl + ltl * p_ckf.transpose() * ltl), Eigen::EigenvaluesOnly);
  const double gamma = ratio * std::sqrt(std::max(eig.eigenvalues().maxCoeff(), 0.0));
  const Mat<N, N> bracket = info - ltl / (gamma * gamma);
  Eigen::LLT<Mat<N, N>> llt(0.5 * (bracket + bracket.transpose()));
  if (!(gamma > 0.0) || llt.info() != Eigen::Success || !bracket.allFinite()) {
    cubatureUpdate<N, M, K>(x, p, m, y, r);
    return 0.0;
  }
  const Mat<M, M> pzz = m.pzz + r;
  x += m.pxz * pzz.inverse() * y;
  p = llt.solve(Mat<N, N>::Identity());
  p = 0.5 * (p + p.transpose());
  return gamma;
}

/// Rank-one Cholesky update of a lower-triangular L: L L^T <- L L^T + sign u u^T (sign ±1).
/// False when a downdate would make the matrix indefinite (L is then left unchanged).
template <int N>
bool choleskyRankOne(Mat<N, N>& l, Vec<N> u, double sign) {
  Mat<N, N> out = l;
  for (int k = 0; k < N; ++k) {
    const double r2 = out(k, k) * out(k, k) + sign * u(k) * u(k);
    if (!(out(k, k) > 0.0) || !(r2 > 0.0)) return false;
    const double r = std::sqrt(r2);
    const double c = r / out(k, k);
    const double s = u(k) / out(k, k);
    out(k, k) = r;
    for (int i = k + 1; i < N; ++i) {
      out(i, k) = (out(i, k) + sign * s * u(i)) / c;
      u(i) = c * u(i) - s * out(i, k);
    }
  }
  l = out;
  return true;
}

/// choleskyRankOne, and when a downdate fails, L recomputed from L L^T + sign u u^T with its
/// eigenvalues floored; returns false in that case (the caller counts it).
template <int N>
bool choleskyRankOneOrRebuild(Mat<N, N>& l, const Vec<N>& u, double sign) {
  if (choleskyRankOne<N>(l, u, sign)) return true;
  l = lowerSquareRoot<N>(l * l.transpose() + sign * u * u.transpose());
  return false;
}

/// The square-root time update through f (Algorithm 3.1, eq. 20-22): the points propagated, the
/// new S from the QR of [sqrt(wc_1) (X_i - x) ..., sqrt(Q)] and a rank-one update with the
/// zeroth point. False when that update had to rebuild S.
template <int N, class F>
bool sqrtUnscentedPredict(Vec<N>& x, Mat<N, N>& s, F&& f, const Mat<N, N>& sqrt_q, double alpha,
                          double beta, double kappa) {
  const auto set = unscentedPoints<N>(x, s, alpha, beta, kappa);
  Mat<N, 2 * N + 1> xs;
  for (int i = 0; i < 2 * N + 1; ++i) xs.col(i) = f(Vec<N>(set.x.col(i)));
  x = xs * set.wm;
  Mat<N, 3 * N> a;  // columns: the 2n outer points' deviations, then sqrt(Q)
  const double w1 = std::sqrt(set.wc(1));
  for (int i = 1; i < 2 * N + 1; ++i) a.col(i - 1) = w1 * (xs.col(i) - x);
  a.template rightCols<N>() = sqrt_q;
  Eigen::HouseholderQR<Mat<3 * N, N>> qr(a.transpose());
  s = qr.matrixQR().template topRows<N>().template triangularView<Eigen::Upper>().transpose();
  // The triangular factor may carry negative diagonal entries; flip those columns' signs.
  for (int i = 0; i < N; ++i)
    if (s(i, i) < 0.0) s.col(i) = -s.col(i);
  const double w0 = set.wc(0);
  return choleskyRankOneOrRebuild<N>(s, std::sqrt(std::abs(w0)) * (xs.col(0) - x),
                                     w0 < 0.0 ? -1.0 : 1.0);
}

/// The square-root measurement update (Algorithm 3.1, eq. 23-28) from the moments of the
/// unscented points `set` (propagate's, whose zs it reuses): S_z from the QR of
/// [sqrt(wc_1) (Z_i - z) ..., sqrt(R)] and the zeroth point, K = P_xz S_z^-T S_z^-1,
/// x <- x + K y, and S downdated by each column of U = K S_z. False when a downdate had to
/// rebuild S.
template <int N, int M>
bool sqrtUnscentedUpdate(Vec<N>& x, Mat<N, N>& s, const PointSet<N, 2 * N + 1>& set,
                         const PointMoments<N, M, 2 * N + 1>& m, const Vec<M>& y,
                         const Mat<M, M>& sqrt_r) {
  Mat<M, 2 * N + M> a;
  const double w1 = std::sqrt(set.wc(1));
  for (int i = 1; i < 2 * N + 1; ++i) a.col(i - 1) = w1 * (m.zs.col(i) - m.z);
  a.template rightCols<M>() = sqrt_r;
  Eigen::HouseholderQR<Mat<2 * N + M, M>> qr(a.transpose());
  Mat<M, M> sz =
      qr.matrixQR().template topRows<M>().template triangularView<Eigen::Upper>().transpose();
  for (int i = 0; i < M; ++i)
    if (sz(i, i) < 0.0) sz.col(i) = -sz.col(i);
  const double w0 = set.wc(0);
  bool ok = choleskyRankOneOrRebuild<M>(sz, std::sqrt(std::abs(w0)) * (m.zs.col(0) - m.z),
                                        w0 < 0.0 ? -1.0 : 1.0);
  const Mat<M, M> pzz = sz * sz.transpose();
  const Mat<N, M> k = m.pxz * pzz.inverse();
  x += k * y;
  const Mat<N, M> u = k * sz;
  for (int i = 0; i < M; ++i) ok = choleskyRankOneOrRebuild<N>(s, u.col(i), -1.0) && ok;
  return ok;
}

}  // namespace uwbloc::loc::kalman
