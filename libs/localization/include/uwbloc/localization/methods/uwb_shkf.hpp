// uwb-shkf: the improved Sage-Husa Kalman filter (improved-sage-husa-kf-uwb-imu-nlos.txt, §2),
// on each range (tightly coupled) with uwb-ekf's constant-velocity state, start, gate and
// quarantine. The paper's equations were lost in extraction; its text fixes the structure, and
// the standard forms below fill it in:
//   - the innovation covariance estimated two ways (paper eq. 25-27): by exponential fading,
//       Ĉ_exp,k = (1 - d_k) Ĉ_exp,k-1 + d_k e_k^2,  d_k = (1 - b) / (1 - b^(k+1))
//     (Sage & Husa 1969; the greenhouse paper's eq. 24), and as the mean of e^2 over a window
//     of variable length N_k = clamp(N0 + K_N |e_k-1|, N0, 10 N0): the window widens when the
//     innovation grows (paper eq. 32, its words: "proportional to the innovation at k-1, and
//     not too short"; the 10 N0 cap keeps its cost bounded);
//   - the adaptive factor β_k (paper eq. 33), from the trend of the innovation: with
//     Δ = |e_k - e_k-1| / sqrt(Ĉ_exp,k-1), slow (Δ <= c0) β = 0, rapid (Δ > c1) β = 1, and
//     β = (Δ - c0) / (c1 - c0) between; the innovation covariance is then
//       C_k = (1 - β_k) Ĉ_exp,k + β_k Ĉ_win,k
//     (paper eq. 34; β ≡ 0 is its SHKF0, β ≡ 1 its SHKF1: `beta=0`, `beta=1`);
//   - the fading factor (paper eq. 28-31 in the simplified strong-tracking form of Zhou & Frank,
//     "Strong tracking filtering of nonlinear time-varying stochastic systems", IJC 65, 1996):
//       λ_k = max(1, (C_k - H Q H^T - R̂_k-1) / (H F P F^T H^T)),  P_k/k-1 = λ_k F P F^T + Q;
//   - the measurement noise R̂: the paper's R̂_k = C_k - H P_k/k-1 H^T (eq. 27,
//     `r_from=innovation`), kept at least r_floor^2, and at least the model's sigma^2 until the
//     anchor's statistics hold N0 innovations; or, by default (`r_from=auto`), from the post-fit
//     residual ε_k = e_k - H (x_k - x_k/k-1): the same exponential and windowed statistics, mixed
//     by the same β, of ε_k^2 + H P_k H^T (Mohamed & Schwarz 1999; kalman/sage_husa.hpp), which
//     is positive by construction and is used from the next range on. Each range's process noise
//     is the constant-velocity model's, wider than a slow robot's motion: at one range a second
//     H P H^T outgrows the ranges' noise, C - H P H^T is negative, and the innovation form held
//     R̂ at its floor (σ/2) for 604 of the MRPT demo's 1 000-odd ranges; the filter, trusting
//     single ranges to 5 cm, took a range of beacon 1 0.6 m short at 184 s and ran 3.6 m off.
// The fading factor is capped at `fading_max`, 1 (off) by default. Applied per range, as this
// tightly coupled filter must, it multiplies the whole F P F^T at the range rate whenever one
// anchor's innovation runs high (an NLOS burst that passes the gate). 2D RMSE [m] on the
// simulated PF-IBAS room (seed 1), the Hanyang LOS A1 / NLOS A1 / NLOS B3 runs and the MRPT demo
// with its manifest's sigma (with the learning start and the restart after an outage;
// `uwbloc compare -m uwb-shkf,uwb-shkf:fading_max=1e6,uwb-shkf:bias=1,uwb-shkf:r_floor=0.01`,
// and the same with r_from=innovation):
//                                  R̂ from the residual             from the innovation
//   defaults                       0.195 0.794 0.778 0.380 0.239    0.191 0.794 0.778 0.380 0.379
//   fading uncapped (1e6)          0.739 0.794 0.778 0.380 0.166    0.669 0.794 0.778 0.380 1.293
//   bias=1 (the Sage-Husa mean r̂)  0.218 0.578 0.770 0.398 1.158    0.230 0.582 0.772 0.402 1.159
//   r_floor=0.01                   0.195 0.911 0.653 0.612 0.239    0.222 0.895 0.709 0.549 0.335
// With 3 or 4 anchors a per-anchor bias is barely observable beside the position, hence off by
// default (it wins on LOS A1 and loses on the room, B3 and the demo). R̂'s floor defaults to half
// the range sigma: from the innovation the windowed and faded statistics otherwise drive R̂ to
// the floor after a run of small innovations, and the filter, then overconfident, refuses the
// next true move (the last row: worse on the room, LOS A1 and B3).
// One statistic per anchor. A range's NLOS probability p (uwb::Range::nlos_probability, from a
// classifier, optional) divides its R by 1 - p; a range with p above `p_reject` is dropped.
#pragma once

#include <deque>
#include <map>

#include "uwbloc/localization/kalman/sage_husa.hpp"
#include "uwbloc/localization/methods/uwb_ekf.hpp"

namespace uwbloc::loc {

struct UwbShkfParams {
  UwbEkfParams ekf;
  double forgetting = 0.99;  ///< b (the paper: 0.99)
  int n0 = 10;               ///< N0, the shortest window (the paper: 10)
  double kn = 10.0;          ///< K_N, window growth per metre of innovation (the paper: 10)
  double c0 = 1.0;           ///< the adaptive factor's thresholds (the paper: 1 and 3.5)
  double c1 = 3.5;
  AutoDouble beta;           ///< fixed β (0: SHKF0, 1: SHKF1); auto: the adaptive factor
  AutoDouble r_floor;        ///< smallest std of R̂ [m]; auto: half the range sigma
  double fading_max = 1.0;   ///< largest fading factor λ (1: off, see above)
  bool bias = false;         ///< estimate each anchor's range bias r̂ (Sage-Husa mean)
  double p_reject = 0.95;    ///< ranges more likely NLOS than this are dropped
  SageHusaRFrom r_from = SageHusaRFrom::kAuto;  ///< auto: the residual

  template <class V>
  void visit(V&& v) {
    ekf.visit(v);
    v("b", forgetting, "forgetting factor of the exponential statistic");
    v("n0", n0, "shortest window of the windowed statistic [ranges]");
    v("kn", kn, "window growth per metre of the previous innovation");
    v("c0", c0, "adaptive factor: normalised innovation change below which beta = 0");
    v("c1", c1, "adaptive factor: change above which beta = 1");
    v("beta", beta, "fixed adaptive factor (0 = SHKF0, 1 = SHKF1), or auto");
    v("r_floor", r_floor, "smallest std kept in the estimated R [m], or auto: half of sigma");
    v("fading_max", fading_max, "largest fading factor (1 = no fading)");
    v("bias", bias, "estimate each anchor's range bias (1) or not (0)");
    v("p_reject", p_reject, "drop ranges whose NLOS probability exceeds this");
    v("r_from", r_from,
      "what the estimated R is learnt from: innovation (C - H P H', the paper's eq. 27), "
      "residual (the post-fit residual eps: eps^2 + H P H', positive by construction), or auto: "
      "the residual");
  }
};

/// On the primary tag (N = 4) or, with two tags or more, on the robot's pose through every tag
/// (N = 6, uwb_ekf.hpp), the statistics then per anchor-tag link.
template <int N>
class UwbShkfT : public UwbEkfT<N> {
 public:
  UwbShkfT(const UwbShkfParams& params, const EstimatorContext& context);

  /// One anchor's statistics.
  struct AnchorStatistic {
    double c_exp = 0.0;
    std::deque<double> window;  ///< the last e^2
    double last_e = 0.0;
    double r = 0.0;   ///< R̂
    double r_exp = 0.0;           ///< R̂ from the residual: its exponential statistic
    std::deque<double> r_window;  ///< and the last ε^2 + H P_k H^T
    double bias = 0.0;
    long k = 0;
  };
  /// The adaptive factor for a normalised innovation change (0 slow, 1 rapid).
  static double adaptiveFactor(double change, double c0, double c1);

 protected:
  using Base = UwbEkfT<N>;
  using Base::p_;
  using Base::params_;
  using Base::stats_;
  using Base::t_;
  using Base::x_;
  using typename Base::Covariance;
  void onStart() override { links_.clear(); }
  bool updateWithRange(const AcceptedRange& r) override;

 private:
  /// R̂ kept at least floor^2 (counted as r_kept_positive).
  void keepAtFloor(double& r, double floor);
  UwbShkfParams sh_;
  std::map<RangeQuarantine::Link, AnchorStatistic> links_;
};

extern template class UwbShkfT<4>;
extern template class UwbShkfT<6>;
using UwbShkf = UwbShkfT<4>;

}  // namespace uwbloc::loc
