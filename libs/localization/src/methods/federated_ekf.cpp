#include "uwbloc/localization/methods/federated_ekf.hpp"

#include <algorithm>
#include <cmath>

namespace uwbloc::loc {

template <int N>
FederatedEkfT<N>::FederatedEkfT(const FederatedEkfParams& params, const EstimatorContext& context)
    : UwbEkfT<N>(params.ekf, context), fold_blind_(params.fold_blind) {
  std::vector<int> ids;
  for (const auto& a : context.anchors) ids.push_back(a.id);
  std::sort(ids.begin(), ids.end());
  const int groups = std::max(1, std::min<int>(params.groups, static_cast<int>(ids.size())));
  for (std::size_t i = 0; i < ids.size(); ++i) group_of_[ids[i]] = static_cast<int>(i) % groups;
  locals_.resize(groups);
}

template <int N>
void FederatedEkfT<N>::resetLocals() {
  const double n = static_cast<double>(locals_.size());  // 1 / β_i
  for (auto& l : locals_) l = {x_, n * p_, t_, false};
}

template <int N>
void FederatedEkfT<N>::onStart() {
  resetLocals();
}

template <int N>
void FederatedEkfT<N>::fuse() {
  Covariance info = Covariance::Zero();
  State info_x = State::Zero();
  for (const auto& l : locals_) {
    // (N = 6: the local headings are never wrapped, only the master's, so they stay on one
    // branch of the angle and their mean is the right one.)
    const Covariance li = l.p.inverse();
    info += li;
    info_x += li * l.x;
  }
  p_ = info.inverse();
  p_ = 0.5 * (p_ + p_.transpose());
  x_ = p_ * info_x;
}

template <int N>
bool FederatedEkfT<N>::updateWithRange(const AcceptedRange& r) {
  const auto g = group_of_.find(r.measurement.anchor_id);
  if (g == group_of_.end()) return false;  // the front end accepts known anchors only
  const double n = static_cast<double>(locals_.size());
  const double t = std::max(t_, r.measurement.t);
  // Every local filter to the range's time, with the shared process noise Q / β_i.
  for (auto& l : locals_) {
    if (t > l.t) {
      Covariance f, q;
      this->transition(t - l.t, f, q, n);
      l.x = f * l.x;
      l.p = f * l.p * f.transpose() + q;
    }
    l.t = t;
  }
  if (t > t_) this->predictTo(t);  // the master too, for the fold test (fuse() replaces it)
  t_ = t;
  Local& local = locals_[g->second];
  typename Base::Jacobian hj;
  const double h = Base::rangeModel(local.x, r, &hj);
  const Eigen::Matrix<double, 1, 1> rv(this->rangeVariance(r));
  const Eigen::Matrix<double, 1, 1> y(r.measurement.range - h);
  const bool used = this->admit(
      r, y(0),
      kalman::inGate(kalman::innovate<N, 1>(local.p, y, hj, rv), uwb::ChiSquareGate(params_.gate)));
  if (used) {
    if (fold_blind_) {
      const auto fold =
          rangeFold(kalman::cubaturePoints<N>(x_, p_), x_, r, std::sqrt(rv(0)), this->sideSigmas());
      if (fold) {
        ++this->stats_.events[fold->event()];
        if (!fold->side_known) Base::blindAlong(hj, fold->axis);
      }
    }
    kalman::josephUpdate<N, 1>(local.x, local.p, kalman::innovate<N, 1>(local.p, y, hj, rv), hj,
                               rv);
    local.measured = true;
  }
  fuse();
  if (std::all_of(locals_.begin(), locals_.end(), [](const Local& l) { return l.measured; }))
    resetLocals();
  return used;
}

template class FederatedEkfT<4>;
template class FederatedEkfT<6>;

}  // namespace uwbloc::loc
