#include "uwbloc/localization/methods/federated_ekf.hpp"

#include <algorithm>

namespace uwbloc::loc {

FederatedEkf::FederatedEkf(const FederatedEkfParams& params, const EstimatorContext& context)
    : UwbEkf(params.ekf, context) {
  std::vector<int> ids;
  for (const auto& a : context.anchors) ids.push_back(a.id);
  std::sort(ids.begin(), ids.end());
  const int groups = std::max(1, std::min<int>(params.groups, static_cast<int>(ids.size())));
  for (std::size_t i = 0; i < ids.size(); ++i) group_of_[ids[i]] = static_cast<int>(i) % groups;
  locals_.resize(groups);
}

void FederatedEkf::resetLocals() {
  const double n = static_cast<double>(locals_.size());  // 1 / β_i
  for (auto& l : locals_) l = {x_, n * p_, t_, false};
}

void FederatedEkf::onStart() { resetLocals(); }

void FederatedEkf::fuse() {
  Eigen::Matrix4d info = Eigen::Matrix4d::Zero();
  Eigen::Vector4d info_x = Eigen::Vector4d::Zero();
  for (const auto& l : locals_) {
    const Eigen::Matrix4d li = l.p.inverse();
    info += li;
    info_x += li * l.x;
  }
  p_ = info.inverse();
  p_ = 0.5 * (p_ + p_.transpose());
  x_ = p_ * info_x;
}

bool FederatedEkf::updateWithRange(const AcceptedRange& r) {
  const auto g = group_of_.find(r.measurement.anchor_id);
  if (g == group_of_.end()) return false;  // the front end accepts known anchors only
  const double n = static_cast<double>(locals_.size());
  const double t = std::max(t_, r.measurement.t);
  // Every local filter to the range's time, with the shared process noise Q / β_i.
  for (auto& l : locals_) {
    if (t > l.t)
      kalman::predictConstantVelocity(l.x, l.p, t - l.t, n * params_.accel_psd,
                                      params_.velocity_tau);
    l.t = t;
  }
  t_ = t;
  Local& local = locals_[g->second];
  Eigen::Matrix<double, 1, 4> hj;
  const double h = rangeModel(local.x, r, &hj);
  const Eigen::Matrix<double, 1, 1> rv(rangeVariance(r));
  const auto inn = kalman::innovate<4, 1>(
      local.p, Eigen::Matrix<double, 1, 1>(r.measurement.range - h), hj, rv);
  const bool used = admit(r.measurement.anchor_id, inn.y(0),
                          kalman::inGate(inn, uwb::ChiSquareGate(params_.gate)));
  if (used) {
    kalman::josephUpdate<4, 1>(local.x, local.p, inn, hj, rv);
    local.measured = true;
  }
  fuse();
  if (std::all_of(locals_.begin(), locals_.end(), [](const Local& l) { return l.measured; }))
    resetLocals();
  return used;
}

}  // namespace uwbloc::loc
