// The H∞ cubature paper's filters (adaptive-hinf-ckf-uwb-ins.txt) and its comparison filters, on
// each range (tightly coupled) with uwb-ekf's state, start, gate and quarantine (uwb_ekf.hpp):
//   - uwb-ckf: the cubature Kalman filter (kalman/cubature.hpp, Arasaratnam & Haykin 2009);
//   - uwb-hinf-ckf: the H∞ cubature filter, γ = `hinf` times the smallest feasible on the
//     position (kalman/cubature.hpp);
//   - uwb-iahckf: the paper's improved adaptive H∞ CKF: the H∞ CKF with a Sage-Husa statistic
//     per anchor (r̂ the range bias, R̂ its variance, the greenhouse paper's eq. 16 and 24 with
//     H P H^T replaced by the points' P_zz) and the IGG-III robust factor on R: for the
//     normalised innovation v = |e| / sqrt(P_zz + R̂),
//       v <= k0: R unchanged;  k0 < v <= k1: R × (v / k0) ((k1 - k0) / (k1 - v))^2;  v > k1:
//       dropped
//     (Yang, Song & Xu, "Adaptively robust filtering for kinematic geodetic positioning",
//     J. Geodesy 75, 2001, the three-segment equivalent weight; the paper's eq. was lost).
//     The paper's NLOS test, |UWB - INS| > 0.24 m, is the floor under it: a range whose
//     innovation is within `nlos_threshold` is never down-weighted, and only ranges below the
//     threshold or within k0 feed the statistics (an NLOS burst would otherwise become R̂);
//   - uwb-srukf: the square-root unscented filter (van der Merwe & Wan 2001; the paper compares
//     an improved variant, ISRUKF, whose changes were lost with its equations).
// A range that folds over the points (rangeFold: the tag near the line through two anchors) is
// taken by the EKF's update (`fold_blind`, on by default): blind along the fold while the mean
// is near it, linearised at the mean once the range tells the mean's side.
// The constant-velocity time update is linear, so the cubature filters propagate it exactly
// (F P F^T + Q, as the points would); the square-root filter propagates its points and S.
// Each is uwb-ekf's UwbEkfT<N>: on the primary tag (N = 4) or, with two tags or more, on the
// robot's pose through every tag's lever arm (N = 6, 2N cubature or 2N + 1 unscented points,
// the heading's std held at most 60 deg before they are formed: UwbEkfT::boundHeadingSpread);
// the H∞ bound stays on the position.
#pragma once

#include <map>

#include "uwbloc/localization/kalman/cubature.hpp"
#include "uwbloc/localization/kalman/sage_husa.hpp"
#include "uwbloc/localization/methods/uwb_ekf.hpp"

namespace uwbloc::loc {

struct UwbCkfParams {
  UwbEkfParams ekf;
  double hinf = 0.0;  ///< γ over the smallest feasible γ (> 1); 0 = the plain CKF update
  bool fold_blind = true;  ///< a range that folds over the points: the EKF's, blind across it

  template <class V>
  void visit(V&& v) {
    ekf.visit(v);
    v("hinf", hinf,
      "H-infinity bound as a multiple (> 1) of the smallest feasible gamma on the position; "
      "larger is closer to the CKF; 0 = plain CKF");
    v("fold_blind", fold_blind, kFoldBlindHelp);
  }
};

template <int N>
class UwbCkfT : public UwbEkfT<N> {
 public:
  UwbCkfT(const UwbCkfParams& params, const EstimatorContext& context);

 protected:
  using Base = UwbEkfT<N>;
  using Base::p_;
  using Base::stats_;
  using Base::x_;
  using typename Base::RangePrediction;
  RangePrediction predictRange(const AcceptedRange& r) override;
  void correctWithRange(const AcceptedRange& r, double y, const RangePrediction& pred) override;
  /// The CKF or H∞ update with range noise `r_var`; the EKF's, blind along the fold, when the
  /// last predictRange found the range folding over the points.
  void cubatureCorrect(double y, double r_var);
  /// The predicted range's own variance (no R) of the last predictRange: the points' P_zz, or
  /// H P H^T where the range folded over them.
  double predictedRangeVariance() const { return pzz_; }

  double hinf_;
  bool fold_blind_;
  std::optional<RangeFold> fold_;  ///< the last predictRange's fold (rangeFold)
  double pzz_ = 0.0;
  kalman::PointMoments<N, 1, 2 * N> moments_;  ///< of the last predictRange
};

struct UwbIahCkfParams {
  UwbCkfParams ckf = [] {
    UwbCkfParams p;
    p.hinf = 5.0;
    return p;
  }();
  double forgetting = 0.97;     ///< b of the Sage-Husa weight d_k
  double k0 = 2.0;              ///< IGG-III: below, R is kept [std]
  double k1 = 5.0;              ///< IGG-III: above, the range is dropped [std]
  double nlos_threshold = 0.24; ///< |innovation| below which a range is never down-weighted [m]
  AutoDouble r_floor;           ///< smallest std of R̂ [m]; auto: half the range sigma
  bool bias = true;             ///< estimate each anchor's range bias r̂
  AutoDouble bias_max;          ///< largest |r̂| [m]; auto: twice the range sigma
  AutoDouble prior_steps;       ///< the steps sigma^2 and r̂ = 0 count as (sageHusaStartStep)
  SageHusaRFrom r_from = SageHusaRFrom::kAuto;  ///< auto: the residual
  long priorSteps() const { return kalman::sageHusaStartStep(prior_steps.value, forgetting); }

  template <class V>
  void visit(V&& v) {
    ckf.visit(v);
    v("bias", bias, "estimate each anchor's range bias (1) or not (0)");
    v("bias_max", bias_max,
      "largest |estimated bias| [m], or auto: twice sigma (the learning start removes a constant "
      "bias before the filter runs; beyond, the estimate follows the filter's own error)");
    v("b", forgetting, "forgetting factor of the noise statistics, d_k = (1-b)/(1-b^(k+1))");
    v("k0", k0, "IGG-III: normalised innovations up to k0 keep R");
    v("k1", k1, "IGG-III: beyond k1 the range is dropped; between, R is inflated");
    v("nlos_threshold", nlos_threshold,
      "innovations within this are never down-weighted (the paper's UWB-vs-INS 0.24 m) [m]");
    v("r_floor", r_floor, "smallest std kept in the estimated R [m], or auto: half of sigma");
    v("prior_steps", prior_steps, kalman::kPriorStepsHelp);
    v("r_from", r_from,
      "what the estimated R is learnt from: innovation (e^2 - P_zz, eq. 16 with the points' "
      "P_zz), residual (the post-fit residual at the updated mean: eps^2 + H P H', positive by "
      "construction), or auto: the residual");
  }
};

template <int N>
class UwbIahCkfT : public UwbCkfT<N> {
 public:
  UwbIahCkfT(const UwbIahCkfParams& params, const EstimatorContext& context);

 protected:
  using Base = UwbCkfT<N>;
  using Base::params_;
  using Base::stats_;
  void onStart() override { links_.clear(); }
  bool updateWithRange(const AcceptedRange& r) override;

 private:
  UwbIahCkfParams iah_;
  std::map<RangeQuarantine::Link, kalman::SageHusaMeasurement<1>> links_;
};

/// Throws ParamError unless `hinf` is 0 (off) or above 1 (a multiple of the smallest feasible γ).
void checkHinfRatio(double hinf);

/// The IGG-III variance factor for a normalised innovation v (1 up to k0, infinite beyond k1).
double iggIIIFactor(double v, double k0, double k1);

struct UwbSrukfParams {
  UwbEkfParams ekf;
  double alpha = 1.0;  ///< spread of the points
  double beta = 2.0;   ///< prior knowledge of the distribution (2: Gaussian)
  double kappa = 0.0;  ///< secondary scaling
  bool fold_blind = true;  ///< a range that folds over the points: the EKF's, blind across it

  template <class V>
  void visit(V&& v) {
    ekf.visit(v);
    v("ut_alpha", alpha, "unscented spread alpha");
    v("ut_beta", beta, "unscented beta (2 for a Gaussian)");
    v("ut_kappa", kappa,
      "unscented kappa (n + kappa > 0; n = 4, or 6 on a robot with two tags or more)");
    v("fold_blind", fold_blind, kFoldBlindHelp);
  }
};

template <int N>
class UwbSrukfT : public UwbEkfT<N> {
 public:
  UwbSrukfT(const UwbSrukfParams& params, const EstimatorContext& context);

 protected:
  using Base = UwbEkfT<N>;
  using Base::p_;
  using Base::stats_;
  using Base::x_;
  using typename Base::Covariance;
  using typename Base::RangePrediction;
  using typename Base::State;
  void onStart() override;
  void predictTo(double t) override;
  RangePrediction predictRange(const AcceptedRange& r) override;
  void correctWithRange(const AcceptedRange& r, double y, const RangePrediction& pred) override;

 private:
  UwbSrukfParams sr_;
  std::optional<RangeFold> fold_;          ///< the last predictRange's fold (rangeFold)
  Covariance s_ = Covariance::Identity();  ///< P = S S^T
  kalman::PointSet<N, 2 * N + 1> points_;
  kalman::PointMoments<N, 1, 2 * N + 1> moments_;
};

extern template class UwbCkfT<4>;
extern template class UwbCkfT<6>;
extern template class UwbIahCkfT<4>;
extern template class UwbIahCkfT<6>;
extern template class UwbSrukfT<4>;
extern template class UwbSrukfT<6>;
using UwbCkf = UwbCkfT<4>;
using UwbIahCkf = UwbIahCkfT<4>;
using UwbSrukf = UwbSrukfT<4>;

}  // namespace uwbloc::loc
