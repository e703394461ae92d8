// uwb-akf and uwb-iakf: the greenhouse paper's adaptive Kalman filters (iakf-greenhouse-uwb.txt,
// §1.3-1.4), loosely coupled on the multilateration fix as in the paper's set-up: uwb-kf's
// constant-velocity state and fix measurement, with the noise statistics q̂, Q̂, r̂, R̂ estimated
// on line by the Sage-Husa step (kalman/sage_husa.hpp: eq. 15-16 and 24) and, for uwb-iakf, the
// divergence test and covariance inflation of eq. (17)-(23).
//
// mode=fix (the default) is that set-up. mode=ranges couples them tightly instead: uwb-ekf's
// per-range EKF (same start, same constant-velocity state, same gate and quarantine) with the
// Sage-Husa step on each range's innovation, one measurement statistic (r̂, R̂: the anchor's
// range bias and variance) per anchor, R̂ from the post-fit residual (r_from); the process noise
// stays the constant-velocity model's (adapted range by range it drifted: see uwb_akf.cpp).
//
// The statistics start from uwb-kf's and uwb-ekf's models: Q̂_0 the constant-velocity process
// noise over the data's first interval, R̂_0 the first fix's covariance (fix) or sigma^2 (ranges),
// q̂_0 = r̂_0 = 0; on the fix Q̂ is then kept at or above the model's Q over each interval
// (q_floor), and R̂ at or above each fix's variance along its best-determined axis (r_floor_fix).
// The fix mode does not gate: the paper's filters adapt to what a gate would drop. The range mode
// gates as uwb-ekf does, or a faulty anchor's ranges come back as its error shrinks through the
// gate (the MRPT demo's beacon 1: 5.53 m without the quarantine).
#pragma once

#include <map>

#include "uwbloc/localization/kalman/sage_husa.hpp"
#include "uwbloc/localization/methods/uwb_ekf.hpp"
#include "uwbloc/localization/methods/uwb_kf.hpp"

namespace uwbloc::loc {

enum class AkfMode { kFix, kRanges };
constexpr std::array<EnumName<AkfMode>, 2> enumNames(AkfMode) {
  return {{{AkfMode::kFix, "fix"}, {AkfMode::kRanges, "ranges"}}};
}

/// Which noise means the Sage-Husa step estimates besides the covariances: both (eq. 16 as the
/// paper has it), q̂ alone, r̂ alone, none; auto: none on the fix, r̂ (each anchor's range bias)
/// on the ranges. On the fix neither mean can be told from the state: a constant r̂ is the
/// track shifted (the filter that learns it settles wherever it is, e = z - Hx - r̂ = 0), q̂ the
/// running mean of the corrections K e, an integrator of the innovations. With both, the track
/// walks away from the fixes on long runs (CARMEN aces+uwb, 1365 s: uwb-akf 2.09 m, uwb-iakf
/// 3.79 m; without them 0.49 and 0.40 m). A tightly coupled filter's r̂ is per anchor, not a
/// shift of the track, and its q̂ is never estimated (the model's over each interval).
enum class AkfMeans { kAuto, kBoth, kProcess, kMeasurement, kNone };
constexpr std::array<EnumName<AkfMeans>, 5> enumNames(AkfMeans) {
  return {{{AkfMeans::kAuto, "auto"},
           {AkfMeans::kBoth, "qr"},
           {AkfMeans::kProcess, "q"},
           {AkfMeans::kMeasurement, "r"},
           {AkfMeans::kNone, "none"}}};
}

struct UwbAkfParams {
  AkfMode mode = AkfMode::kFix;
  UwbKfParams kf;
  double forgetting = 0.97;  ///< b of eq. (24), in [0.95, 0.99] in the paper
  double gamma = 0.0;        ///< eq. (17)'s bound; 0 = no divergence test (AKF); uwb-iakf: 1
  double r_floor = 0.01;     ///< smallest std of R̂'s eigenvalues [m] (the positivity guard)
  AkfMeans means = AkfMeans::kAuto;
  SageHusaRFrom r_from = SageHusaRFrom::kAuto;
  EkfStart start = EkfStart::kStartPose;  ///< mode=ranges: where it starts (uwb-ekf's key)
  /// Whether R̂ comes from the post-fit residual, `auto` resolved for the mode.
  bool rFromResidual() const {
    return r_from == SageHusaRFrom::kResidual ||
           (r_from == SageHusaRFrom::kAuto && mode == AkfMode::kRanges);
  }
  /// On the fix: Q̂ kept at or above the constant-velocity model's process noise over each
  /// interval, with q learnt as uwb-kf learns it (Q̂ - Q_model projected onto the positive
  /// semidefinite matrices). Q̂ and R̂ enter the innovation's covariance only through their sum
  /// (E[e e^T] = H (Φ P Φ^T + Q̂) H^T + R̂), so the innovations cannot tell them apart: a filter
  /// that falls behind on a turn reads its lag as measurement noise, R̂ grows, the gain falls,
  /// K e e^T K^T shrinks with it, and the lag grows (CMU Plaza2: uwb-akf 2.44 m, R̂ 3-8 m^2
  /// against a fix error of about 0.5 m^2; the MRPT demo 0.443 m against uwb-kf's 0.171). The
  /// floor stops Q̂ from following R̂ down; the adaptation may still raise it.
  bool q_floor = true;
  /// On the fix: R̂'s eigenvalues kept at or above the fix's own variance along its
  /// best-determined axis (its covariance's smaller eigenvalue: the range sigma through the
  /// anchors' geometry), not only at r_floor. From the innovations, R̂ = e e^T - H P H^T falls
  /// below it wherever P carries Q̂'s floor or the divergence test's inflation: uwb-iakf kept R̂
  /// at the 0.01 m guard at 1170 of 1201 fixes on multitag_room and trusted each fix as if its
  /// std were 1 cm (0.033 m; 0.031 m with this floor). Its full covariance as the floor cost the
  /// MRPT demo, whose fixes from two anchors are wide along one axis (uwb-akf 0.175 -> 0.185 m).
  bool r_floor_fix = true;
  /// The steps the starting statistics (R̂_0: the fix's covariance, or sigma^2 per anchor; Q̂_0:
  /// the model's) count as (kalman::sageHusaStartStep).
  AutoDouble prior_steps;
  long priorSteps() const { return kalman::sageHusaStartStep(prior_steps.value, forgetting); }
  /// Whether q̂ (`process`) or r̂ (else) is estimated, `auto` resolved for the mode.
  bool estimatesMean(bool process) const {
    const AkfMeans m = means != AkfMeans::kAuto
                           ? means
                           : (mode == AkfMode::kFix ? AkfMeans::kNone : AkfMeans::kMeasurement);
    return m == AkfMeans::kBoth || m == (process ? AkfMeans::kProcess : AkfMeans::kMeasurement);
  }

  template <class V>
  void visit(V&& v) {
    v("mode", mode, "fix: on the multilateration fix (the paper); ranges: on each range (tight)");
    kf.visit(v);
    v("b", forgetting, "forgetting factor of the noise statistics, d_k = (1-b)/(1-b^(k+1))");
    v("gamma", gamma,
      "divergence bound: e'e > gamma tr(HPH'+R) inflates P (eq. 17-23); 0 = off (plain AKF)");
    v("r_floor", r_floor, "smallest std kept in the estimated R [m] (positive definiteness)");
    v("q_floor", q_floor,
      "on the fix: the estimated Q kept at or above the constant-velocity model's over each "
      "interval, q learnt as uwb-kf learns it (the innovations give Q+R only as a sum: without "
      "the floor a lagging filter reads its lag as R and falls further behind); 0: eq. 16 alone");
    v("r_floor_fix", r_floor_fix,
      "on the fix: the estimated R's eigenvalues kept at or above the fix's own variance along "
      "its best-determined axis (the range sigma through the geometry); 0: r_floor alone");
    v("prior_steps", prior_steps, kalman::kPriorStepsHelp);
    v("r_from", r_from,
      "what the estimated R is learnt from: innovation (eq. 25: e e' - H P H'), residual (the "
      "post-fit residual eps: eps eps' + H P H', positive by construction), or auto: "
      "innovation on the fix, residual on the ranges");
    v("start", start,
      "mode=ranges: start at the start pose (start) or at the first multilateration fix (fix); "
      "on the fix it always starts from the fix");
    v("means", means,
      "noise means estimated besides the covariances: qr (q-hat and r-hat, eq. 16), q, r, none, "
      "or auto: none on the fix (neither can be told from the state there), r (each anchor's "
      "bias) on the ranges");
  }
};

class UwbAkf : public UwbKf {
 public:
  UwbAkf(const UwbAkfParams& params, const EstimatorContext& context);

 protected:
  void start(const uwb::Fix& fix) override;
  bool predictAndUpdate(const uwb::Fix& fix, double dt) override;
  /// R and Q are estimated from the innovations (Sage-Husa): the learnt std and q would only
  /// seed them, and they seed them worse. A std learnt over NLOS-heavy ranges seeds R wide and
  /// blunts the divergence test (uwb-iakf on the intel log with simulated UWB: 12.9 m with it,
  /// 2.24 m without); a raised q as Q̂'s seed cost uwb-akf on Hanyang NLOS B3 (0.504 against
  /// 0.487 m).
  bool estimatesOwnNoise() const override { return true; }
  /// The learnt q, as Q̂'s floor only (q_floor; the range std stays unlearnt, above). As the
  /// floor it helps on NLOS B3 (0.471 -> 0.441 m).
  void learn(const EstimatorStatistics& learnt) override;

 private:
  UwbAkfParams akf_;
  kalman::SageHusaProcess<4> process_;
  kalman::SageHusaMeasurement<2> measurement_;
};

/// mode=ranges: on the primary tag (N = 4) or, with two tags or more and tags=auto, on the
/// robot's pose through every tag (N = 6, uwb_ekf.hpp), the statistics then per anchor-tag link.
template <int N>
class UwbAkfRanges : public UwbEkfT<N> {
 public:
  UwbAkfRanges(const UwbAkfParams& params, const EstimatorContext& context);

 protected:
  using Base = UwbEkfT<N>;
  using Base::p_;
  using Base::params_;
  using Base::stats_;
  using Base::t_;
  using Base::x_;
  void onStart() override;
  bool updateWithRange(const AcceptedRange& r) override;

 private:
  UwbAkfParams akf_;
  std::map<RangeQuarantine::Link, kalman::SageHusaMeasurement<1>> links_;
};

extern template class UwbAkfRanges<4>;
extern template class UwbAkfRanges<6>;

/// The estimator for `params.mode`.
std::unique_ptr<Estimator> makeUwbAkf(const UwbAkfParams& params, const EstimatorContext& context);

}  // namespace uwbloc::loc
