// uwb-akf and uwb-iakf: the greenhouse paper's adaptive Kalman filters (iakf-greenhouse-uwb.txt,
// §1.3-1.4), loosely coupled on the multilateration fix as in the paper's set-up: uwb-kf's
// constant-velocity state and fix measurement, with the noise statistics q̂, Q̂, r̂, R̂ estimated
// on line by the Sage-Husa step (kalman/sage_husa.hpp: eq. 15-16 and 24) and, for uwb-iakf, the
// divergence test and covariance inflation of eq. (17)-(23).
//
// The statistics start from uwb-kf's models: Q̂_0 the constant-velocity process noise over the
// data's first epoch interval, R̂_0 the first fix's covariance, q̂_0 = r̂_0 = 0.
#pragma once

#include "uwbloc/localization/kalman/sage_husa.hpp"
#include "uwbloc/localization/methods/uwb_kf.hpp"

namespace uwbloc::loc {

struct UwbAkfParams {
  UwbKfParams kf;
  double forgetting = 0.97;  ///< b of eq. (24), in [0.95, 0.99] in the paper
  double gamma = 0.0;        ///< eq. (17)'s bound; 0 = no divergence test (AKF); uwb-iakf: 1
  double r_floor = 0.01;     ///< smallest std of R̂'s eigenvalues [m] (the positivity guard)

  template <class V>
  void visit(V&& v) {
    kf.visit(v);
    v("b", forgetting, "forgetting factor of the noise statistics, d_k = (1-b)/(1-b^(k+1))");
    v("gamma", gamma,
      "divergence bound: e'e > gamma tr(HPH'+R) inflates P (eq. 17-23); 0 = off (plain AKF)");
    v("r_floor", r_floor, "smallest std kept in the estimated R [m] (positive definiteness)");
  }
};

class UwbAkf : public UwbKf {
 public:
  UwbAkf(const UwbAkfParams& params, const EstimatorContext& context);

 protected:
  void start(const uwb::Fix& fix) override;
  bool predictAndUpdate(const uwb::Fix& fix, double dt) override;

 private:
  UwbAkfParams akf_;
  kalman::SageHusaNoise<4, 2> noise_;
  bool noise_started_ = false;
};

}  // namespace uwbloc::loc
