// federated-ekf: the H∞ cubature paper's comparison filter (adaptive-hinf-ckf-uwb-ins.txt, Table
// 3), Carlson's federated filter ("Federated square root filter for decentralized parallel
// processes", IEEE TAES 26(3), 1990) in the fusion-reset form. Local EKFs (uwb-ekf's constant-
// velocity state, range model, gate and quarantine) each take the ranges of one group of anchors
// (the anchors in id order, dealt round-robin into `groups`); with the information-sharing
// factors β_i = 1 / groups each runs with Q / β_i and restarts from P_g / β_i. The master
// filter fuses them after every range,
//   P_g = (Σ P_i^-1)^-1,   x_g = P_g Σ P_i^-1 x_i,
// and resets them to (x_g, P_g / β_i) once every group has measured since the last reset. The
// paper's federated filter fuses a UWB and an INS sub-filter; without an IMU the sub-filters are
// anchor groups, which keeps the decentralised structure (and its information loss). On a robot
// with two tags or more the local filters hold uwb-ekf's pose state (N = 6, uwb_ekf.hpp). A range
// that folds over the fused estimate's spread (rangeFold, on the master's cubature points: the
// tag near the line through two anchors) updates the local filter blind across the fold
// (`fold_blind`): each local runs on a share of the information (P / beta_i), so the slope at its
// mean threw it across the line of beacons 2 and 3 on the MRPT demo. The fold is judged on the
// master's spread, not the local's: that one is wider by 1 / beta_i, and on it every range of an
// anchor 2 m off the line folded, its update blinded along the anchor's own direction.
#pragma once

#include <vector>

#include "uwbloc/localization/methods/uwb_ekf.hpp"

namespace uwbloc::loc {

struct FederatedEkfParams {
  UwbEkfParams ekf;
  int groups = 2;  ///< local filters (anchor groups)
  bool fold_blind = true;  ///< a range that folds over a local filter's spread: blind across it

  template <class V>
  void visit(V&& v) {
    ekf.visit(v);
    v("groups", groups, "local filters, each on one group of anchors (round-robin in id order)");
    v("fold_blind", fold_blind, kFoldBlindHelp);
  }
};

template <int N>
class FederatedEkfT : public UwbEkfT<N> {
 public:
  FederatedEkfT(const FederatedEkfParams& params, const EstimatorContext& context);

 protected:
  using Base = UwbEkfT<N>;
  using Base::p_;
  using Base::params_;
  using Base::t_;
  using Base::x_;
  using typename Base::Covariance;
  using typename Base::State;
  void onStart() override;
  bool updateWithRange(const AcceptedRange& r) override;

 private:
  struct Local {
    State x;
    Covariance p;
    double t = 0.0;
    bool measured = false;
  };
  void fuse();
  void resetLocals();

  bool fold_blind_;
  std::vector<Local> locals_;
  std::map<int, int> group_of_;  ///< anchor id -> local filter
};

extern template class FederatedEkfT<4>;
extern template class FederatedEkfT<6>;
using FederatedEkf = FederatedEkfT<4>;

}  // namespace uwbloc::loc
