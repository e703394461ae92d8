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
// and each projection is reported (SageHusaStep).
//
// R̂ from the residual instead (SageHusaMeasurement::from_residual): with the post-fit residual
// ε = z - h(x_k) ≈ e - H (x_k - x_{k/k-1}), E[ε ε^T] = R - H P_k H^T, so
//   R̂_k = (1 - d_k) R̂_{k-1} + d_k (ε ε^T + H P_k H^T)
// (the residual-based estimate of Mohamed & Schwarz, "Adaptive Kalman filtering for INS/GPS",
// J. Geodesy 73, 1999, with the fading weight d_k in place of their moving window). It adds two
// positive semidefinite terms, so it cannot go indefinite. The innovation form reads an
// over-wide prediction (a process noise larger than the motion's) as a small R: e e^T - H P H^T
// is then negative on average and R̂ sits at its floor, the gain rises and the filter follows
// single measurements. The residual form sees the same filter's fit, which the wide prediction
// makes closer, and its H P_k H^T, which then tends to R.
//
// Divergence (IAKF, eq. 20): e^T e > gamma tr(H P_{k/k-1} H^T + R̂). Then eq. (21)-(22):
//   P_{k/k-1} = C_k Φ P_{k-1} Φ^T + Q̂,  C_k = (e^T e - tr(H Q̂ H^T + R̂)) / tr(H Φ P Φ^T H^T),
// with C_k kept at least 1 (it inflates; a C_k below 1 would shrink P when the filter diverges).
#pragma once

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <optional>

#include "uwbloc/localization/kalman/kalman.hpp"
#include "uwbloc/localization/params.hpp"

namespace uwbloc::loc {

/// Where a filter's R̂ is estimated from: the innovation (the greenhouse paper's eq. 25 as
/// printed, e e^T - H P_{k/k-1} H^T), the post-fit residual (ε ε^T + H P_k H^T, above), or auto,
/// which each filter resolves: uwb-akf the innovation on the fix (the paper's set-up) and the
/// residual on the ranges, uwb-shkf the residual. On the ranges the process noise is the
/// constant-velocity model's, wider than a slow robot's motion: e^2 - H P H^T is then negative
/// for most ranges and R̂ sits at its floor. uwb-akf:mode=ranges on the MRPT demo: each
/// anchor's R̂ at the 0.01 m floor, the filter followed single ranges onto the mirror image of
/// the track across the two anchors left when beacon 1 fails (3.45 m; with the residual
/// 0.213 m); uwb-shkf there (with the manifest's σ), its R̂ at its floor (σ/2) for 604 of about
/// 1 000 ranges, took a range of beacon 1 0.6 m short at 184 s as a 5 cm one and ran 3.6 m off
/// (0.379 m; from the residual 0.239 m).
enum class SageHusaRFrom { kAuto, kInnovation, kResidual };
constexpr std::array<EnumName<SageHusaRFrom>, 3> enumNames(SageHusaRFrom) {
  return {{{SageHusaRFrom::kAuto, "auto"},
           {SageHusaRFrom::kInnovation, "innovation"},
           {SageHusaRFrom::kResidual, "residual"}}};
}

}  // namespace uwbloc::loc

namespace uwbloc::loc::kalman {

/// The estimated process noise: mean q̂, covariance Q̂, and the step count k of its d_k.
template <int N>
struct SageHusaProcess {
  Vec<N> q = Vec<N>::Zero();
  Mat<N, N> Q = Mat<N, N>::Identity();
  long k = 0;
  bool mean = true;  ///< q̂ estimated (false: held at zero, Q̂ alone adapted)
};

/// The estimated measurement noise: mean r̂, covariance R̂, and the step count k of its d_k (a
/// tightly coupled filter keeps one per anchor).
template <int M>
struct SageHusaMeasurement {
  Vec<M> r = Vec<M>::Zero();
  Mat<M, M> R = Mat<M, M>::Identity();
  long k = 0;
  bool mean = true;  ///< r̂ estimated (false: held at zero, R̂ alone adapted)
  /// R̂ from the post-fit residual (ε ε^T + H P_k H^T) instead of the innovation (eq. 25).
  bool from_residual = false;
};

/// Eq. (24): the fading weight of step k for forgetting factor b in (0, 1).
inline double sageHusaWeight(double b, long k) {
  return (1.0 - b) / (1.0 - std::pow(b, static_cast<double>(k + 1)));
}

/// The step k at which statistics seeded from a model start (the `prior_steps` key): the steps
/// that seed counts as in d_k. Given: that many (0: the paper's d_0 = 1, where the first
/// innovation replaces the seed); auto: 1 / (1 - b), the statistics' memory (33 at b = 0.97),
/// as if the filter had run that long with them. At k = 0, R̂_1 = e e^T - H P H^T with P still
/// the start's is indefinite or far off, R̂ falls to its floor, and a filter that trusts single
/// ranges to that floor follows them away (uwb-akf:mode=ranges on the simulated static_los: 1 m
/// off over its first 5 s, 0.674 m against uwb-ekf's 0.052).
inline long sageHusaStartStep(const std::optional<double>& prior_steps, double b) {
  return std::lround(prior_steps.value_or(1.0 / (1.0 - b)));
}

/// The `prior_steps` key's help.
inline constexpr const char* kPriorStepsHelp =
    "steps the starting noise statistics (the model's R and Q) count as, k's start in d_k; "
    "auto: 1/(1-b), their memory; 0: the paper's (the first innovation replaces them)";

/// What one adaptive step did.
struct SageHusaStep {
  double d = 0.0;            ///< the weight d_k of the measurement statistics
  bool diverged = false;     ///< eq. (20) held (IAKF only)
  double inflation = 1.0;    ///< C_k of eq. (22) (1 when not diverged)
  bool r_projected = false;  ///< R̂ had an eigenvalue below r_floor^2
  bool q_projected = false;  ///< Q̂ had an eigenvalue below 1e-12
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

/// Eq. (15) lines 1-2, kept for the update: the state before, Φ P Φ^T, and Φ.
template <int N>
struct SageHusaPrediction {
  Vec<N> x_prev;
  Mat<N, N> fpf;
  Mat<N, N> f;
};

/// Predicts with Φ = `f`: x <- Φ x + q̂, P <- Φ P Φ^T + Q̂.
template <int N>
SageHusaPrediction<N> sageHusaPredict(Vec<N>& x, Mat<N, N>& p, const SageHusaProcess<N>& process,
                                      const Mat<N, N>& f) {
  SageHusaPrediction<N> pred{x, f * p * f.transpose(), f};
  x = f * x + process.q;
  p = pred.fpf + process.Q;
  return pred;
}

/// The update after sageHusaPredict, for a measurement whose innovation against the predicted
/// state is `innovation` (z - h(x_{k/k-1}); for a linear model z - H x_{k/k-1}) with Jacobian
/// One sample of R̂ from the post-fit residual (above): ε = e - H (x_k - x_k/k-1), then
/// ε ε^T + H P_k H^T. `e` is the innovation the update used, `dx` = x_k - x_k/k-1, `p` = P_k.
template <int N, int M>
Mat<M, M> residualNoiseSample(const Vec<M>& e, const Mat<M, N>& h, const Vec<N>& dx,
                              const Mat<N, N>& p) {
  const Vec<M> residual = e - h * dx;
  return residual * residual.transpose() + h * p * h.transpose();
}

/// `h`: eq. (15) lines 3-6 (the toolkit's Joseph form) with the divergence test and inflation of
/// eq. (17)-(23) when `gamma` > 0, then the statistics of eq. (16). `process` is updated only
/// when given (a tightly coupled filter updates it once per range, like the measurement's).
template <int N, int M>
SageHusaStep sageHusaUpdate(Vec<N>& x, Mat<N, N>& p, const SageHusaPrediction<N>& pred,
                            SageHusaProcess<N>* process, SageHusaMeasurement<M>& meas,
                            const Vec<M>& innovation, const Mat<M, N>& h, double b, double gamma,
                            double r_floor) {
  SageHusaStep out;
  // Line 4: the innovation, less the measurement noise mean.
  const Vec<M> e = innovation - meas.r;
  const double ete = e.squaredNorm();
  if (gamma > 0.0) {
    // Eq. (20): diverging when the innovation exceeds gamma times what the filter expects.
    const Mat<M, M> expected = h * p * h.transpose() + meas.R;
    if (ete > gamma * expected.trace()) {
      out.diverged = true;
      const Mat<N, N> q_now = p - pred.fpf;  // Q̂ of this prediction
      const double denom = (h * pred.fpf * h.transpose()).trace();
      const double c =
          denom > 0.0 ? (ete - (h * q_now * h.transpose() + meas.R).trace()) / denom : 1.0;
      out.inflation = std::max(1.0, c);      // eq. (22), inflating only
      p = out.inflation * pred.fpf + q_now;  // eq. (21) / (23)
    }
  }
  const Mat<N, N> p_pred = p;
  const Vec<N> x_pred = x;
  // Lines 3, 5, 6: gain, state, covariance (the toolkit's Joseph form).
  const auto inn = innovate<N, M>(p, e, h, meas.R);
  const Mat<N, M> k = p * h.transpose() * inn.s.inverse();
  josephUpdate<N, M>(x, p, inn, h, meas.R);
  // Eq. (16) with d_k of eq. (24).
  out.d = sageHusaWeight(b, meas.k);
  const double d = out.d;
  if (meas.mean) meas.r = (1.0 - d) * meas.r + d * innovation;
  if (meas.from_residual) {
    meas.R = (1.0 - d) * meas.R + d * residualNoiseSample<N, M>(e, h, x - x_pred, p);
  } else {
    meas.R = (1.0 - d) * meas.R + d * (e * e.transpose() - h * p_pred * h.transpose());
  }
  out.r_projected = projectEigenvalues<M>(meas.R, r_floor * r_floor);
  ++meas.k;
  if (process) {
    const double dq = sageHusaWeight(b, process->k);
    if (process->mean) process->q = (1.0 - dq) * process->q + dq * (x - pred.f * pred.x_prev);
    process->Q =
        (1.0 - dq) * process->Q + dq * (k * e * e.transpose() * k.transpose() + p - pred.fpf);
    out.q_projected = projectEigenvalues<N>(process->Q, 1e-12);
    ++process->k;
  }
  return out;
}

/// One loosely coupled step: sageHusaPredict, then sageHusaUpdate with z = H x + v.
template <int N, int M>
SageHusaStep sageHusaStep(Vec<N>& x, Mat<N, N>& p, SageHusaProcess<N>& process,
                          SageHusaMeasurement<M>& meas, const Mat<N, N>& f, const Vec<M>& z,
                          const Mat<M, N>& h, double b, double gamma, double r_floor) {
  const auto pred = sageHusaPredict<N>(x, p, process, f);
  const Vec<M> innovation = z - h * x;
  return sageHusaUpdate<N, M>(x, p, pred, &process, meas, innovation, h, b, gamma, r_floor);
}

}  // namespace uwbloc::loc::kalman
