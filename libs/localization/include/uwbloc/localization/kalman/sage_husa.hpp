// Sage-Husa adaptive Kalman step (the greenhouse paper, iakf-greenhouse-uwb.txt, §1.3-1.4): the
// filter of eq. (15) with the noise statistics q̂, Q̂, r̂, R̂ of eq. (16) estimated on line with
// the fading weight d_k = (1 - b) / (1 - b^(k+1)) of eq. (24), and, for the improved filter
// (IAKF), the divergence test of eq. (17)-(20) with the covariance inflation C_k of eq. (21)-(23).
//
// Where the printed equations differ from the standard Sage-Husa estimator (Sage & Husa 1969; the
// form in Yang & Gao, "Adaptively robust filtering", J. Geodesy 2001, and in most of the
// literature), the standard form is used, and the difference is named here:
//   - eq. (16) line 3 prints r̂_k = (1 - d) R̂_{k-1} + d (Z_k - H X̂_{k-1}): a matrix mixed into
//     a vector; the standard r̂_k = (1 - d) r̂_{k-1} + d (Z_k - H X̂_{k/k-1}) is used;
//   - eq. (16) line 1 prints X̂_k - X̂_{k-1}; the standard X̂_k - Φ X̂_{k-1} is used;
//   - eq. (16) line 4 and eq. (25) subtract H P_{k-1} H^T; since E[e e^T] = H P_{k/k-1} H^T + R
//     (eq. 18), the standard H P_{k/k-1} H^T is used.
// Either way the R update subtracts a matrix from e e^T and can go indefinite (a small
// innovation gives e e^T - H P H^T < 0). The guard: R̂ is projected onto the symmetric matrices
// with every eigenvalue at least r_floor^2, Q̂ onto those with every eigenvalue at least 1e-12,
// and
// each projection is reported (SageHusaStep).
//
// Divergence (IAKF, eq. 20): e^T e > gamma tr(H P_{k/k-1} H^T + R̂). Then eq. (21)-(22):
//   P_{k/k-1} = C_k Φ P_{k-1} Φ^T + Q̂,  C_k = (e^T e - tr(H Q̂ H^T + R̂)) / tr(H Φ P Φ^T H^T),
// with C_k kept at least 1 (it inflates; a C_k below 1 would shrink P when the filter diverges).
#pragma once

#include <Eigen/Eigenvalues>

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc::kalman {

/// The estimated noise statistics: process noise mean q̂ and covariance Q̂, measurement noise
/// mean r̂ and covariance R̂, and the step count k of d_k.
template <int N, int M>
struct SageHusaNoise {
  Vec<N> q = Vec<N>::Zero();
  Mat<N, N> Q = Mat<N, N>::Identity();
  Vec<M> r = Vec<M>::Zero();
  Mat<M, M> R = Mat<M, M>::Identity();
  long k = 0;
};

/// Eq. (24): the fading weight of step k for forgetting factor b in (0, 1).
inline double sageHusaWeight(double b, long k) {
  return (1.0 - b) / (1.0 - std::pow(b, static_cast<double>(k + 1)));
}

/// What one adaptive step did.
struct SageHusaStep {
  double d = 0.0;            ///< the weight d_k used
  bool diverged = false;     ///< eq. (20) held (IAKF only)
  double inflation = 1.0;    ///< C_k of eq. (22) (1 when not diverged)
  bool r_projected = false;  ///< R̂ had an eigenvalue below r_floor^2
  bool q_projected = false;  ///< Q̂ had a negative eigenvalue
};

/// The symmetric part of `a` with its eigenvalues raised to at least `floor`; true when any was.
template <int K>
bool projectEigenvalues(Mat<K, K>& a, double floor) {
  const Mat<K, K> sym = 0.5 * (a + a.transpose());
  Eigen::SelfAdjointEigenSolver<Mat<K, K>> eig(sym);
  Vec<K> v = eig.eigenvalues();
  const bool below = (v.array() < floor).any();
  v = v.cwiseMax(floor);
  a = eig.eigenvectors() * v.asDiagonal() * eig.eigenvectors().transpose();
  return below;
}

/// One step of eq. (15)-(16) (AKF), or of eq. (15)-(23) with the divergence test when
/// `gamma` > 0 (IAKF): predict with Φ = `f`, update with the measurement `z` = H x + v, then
/// re-estimate the noise statistics. The covariance update is the toolkit's Joseph form.
template <int N, int M>
SageHusaStep sageHusaStep(Vec<N>& x, Mat<N, N>& p, SageHusaNoise<N, M>& noise, const Mat<N, N>& f,
                          const Vec<M>& z, const Mat<M, N>& h, double b, double gamma,
                          double r_floor) {
  SageHusaStep out;
  const Vec<N> x_prev = x;
  const Mat<N, N> fpf = f * p * f.transpose();
  // Eq. (15) lines 1-2.
  const Vec<N> x_pred = f * x_prev + noise.q;
  Mat<N, N> p_pred = fpf + noise.Q;
  // Line 4: the innovation, less the measurement noise mean.
  const Vec<M> innovation = z - h * x_pred;
  const Vec<M> e = innovation - noise.r;
  const double ete = e.squaredNorm();
  if (gamma > 0.0) {
    // Eq. (20): diverging when the innovation exceeds gamma times what the filter expects.
    const Mat<M, M> expected = h * p_pred * h.transpose() + noise.R;
    if (ete > gamma * expected.trace()) {
      out.diverged = true;
      const double denom = (h * fpf * h.transpose()).trace();
      const double c =
          denom > 0.0 ? (ete - (h * noise.Q * h.transpose() + noise.R).trace()) / denom : 1.0;
      out.inflation = std::max(1.0, c);        // eq. (22), inflating only
      p_pred = out.inflation * fpf + noise.Q;  // eq. (21) / (23)
    }
  }
  // Lines 3, 5, 6: gain, state, covariance (the toolkit's Joseph form).
  x = x_pred;
  p = p_pred;
  const auto inn = innovate<N, M>(p, e, h, noise.R);
  const Mat<N, M> k = p * h.transpose() * inn.s.inverse();
  josephUpdate<N, M>(x, p, inn, h, noise.R);
  // Eq. (16) with d_k of eq. (24).
  out.d = sageHusaWeight(b, noise.k);
  const double d = out.d;
  noise.q = (1.0 - d) * noise.q + d * (x - f * x_prev);
  noise.Q = (1.0 - d) * noise.Q + d * (k * e * e.transpose() * k.transpose() + p - fpf);
  noise.r = (1.0 - d) * noise.r + d * innovation;
  noise.R = (1.0 - d) * noise.R + d * (e * e.transpose() - h * p_pred * h.transpose());
  out.q_projected = projectEigenvalues<N>(noise.Q, 1e-12);
  out.r_projected = projectEigenvalues<M>(noise.R, r_floor * r_floor);
  ++noise.k;
  return out;
}

}  // namespace uwbloc::loc::kalman
