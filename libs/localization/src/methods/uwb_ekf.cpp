#include "uwbloc/localization/methods/uwb_ekf.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "uwbloc/localization/methods/uwb_multitag.hpp"
#include "uwbloc/localization/registry.hpp"
#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

namespace {
// N = 6: the (x, y, theta) block of the state.
constexpr int kPoseIndex[3] = {0, 1, UwbEkfT<6>::kTheta};
}  // namespace

template <int N>
UwbEkfT<N>::UwbEkfT(const UwbEkfParams& params, const EstimatorContext& context)
    : UwbEstimator(params.front, context, kMultitag ? TagUse::kAll : TagUse::kPrimary),
      params_(params),
      primary_tag_(primaryTag(context)),
      init_epochs_(params.epoch_window),
      noise_(params.front.sigmaValue()) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
  if (params.start == EkfStart::kStartPose) start_pose_ = context.initial_pose;
  params_.accel_psd = params.q.value.value_or(params.accel_psd);
  start_ = makeLearningStart(params.front.sigma, &params.q, params.learning, context);
}

void learnRangeFilterNoise(const EstimatorStatistics& learnt, UwbEkfParams& params,
                           RangeNoiseModel& noise, EstimatorStatistics& stats) {
  noise.learnFrom(learnt, params.learning.calib_bias, params.front.sigma.isAuto());
  noise.report(stats);
  // The filter's std is then the corrected range's (the ranges are corrected as they come),
  // only ever widened; q only ever raised (range_noise.hpp).
  if (params.front.sigma.isAuto() && learnt.estimated_range_sigma)
    params.front.sigma.value = noise.widened(params.front.sigmaValue(), stats);
  learnAccelPsd(learnt, params.q, params.velocity_tau, params.accel_psd, stats);
  countLearnt(learnt, stats);
}

template <int N>
void UwbEkfT<N>::learn(const EstimatorStatistics& learnt) {
  learnRangeFilterNoise(learnt, params_, noise_, stats_);
}

template <int N>
void UwbEkfT<N>::reset() {
  initialised_ = false;
  quarantine_.clear();
  gated_in_a_row_ = 0;
  recent_.clear();
  for (auto& l : lines_) l.near = false;
  mirror_agreed_ = 0;
  init_epochs_ = EpochBuffer(params_.epoch_window);
}

template <int N>
bool UwbEkfT<N>::leansOnOneAnchor() const {
  if (params_.max_gated <= 0 || recent_.size() < static_cast<size_t>(params_.max_gated))
    return false;
  const double tolerance = readmitTolerance(params_);
  std::optional<int> used;  // the one anchor used
  bool others_answered = false;
  long refused = 0;
  for (const auto& r : recent_) {
    others_answered |= r.anchor != recent_.front().anchor;
    if (r.used) {
      if (used && *used != r.anchor) return false;
      used = r.anchor;
      continue;
    }
    // A refused range close to the state may be readmitted (the quarantine's tolerance): the
    // filter can still come back to its anchor.
    if (!(std::abs(r.innovation) > tolerance)) return false;
    ++refused;
  }
  return others_answered && 2 * refused >= static_cast<long>(recent_.size());
}

template <int N>
void UwbEkfT<N>::transition(double dt, Covariance& f, Covariance& q, double scale) const {
  if constexpr (kMultitag) {
    Eigen::Matrix4d f4, q4;
    constantVelocityModel(dt, scale * params_.accel_psd, f4, q4, params_.velocity_tau);
    f.setIdentity();
    q.setZero();
    f.template topLeftCorner<4, 4>() = f4;
    q.template topLeftCorner<4, 4>() = q4;
    f(kTheta, kOmega) = dt;
    const double w = scale * params_.yaw_accel_psd;
    q(kTheta, kTheta) = w * dt * dt * dt / 3.0;
    q(kTheta, kOmega) = q(kOmega, kTheta) = w * dt * dt / 2.0;
    q(kOmega, kOmega) = w * dt;
  } else {
    constantVelocityModel(dt, scale * params_.accel_psd, f, q, params_.velocity_tau);
  }
}

template <int N>
bool UwbEkfT<N>::boundHeadingSpread(Covariance& p) {
  if constexpr (kMultitag) {
    if (!(p(kTheta, kTheta) > kMaxPointHeadingStd * kMaxPointHeadingStd)) return false;
    const double c = kMaxPointHeadingStd / std::sqrt(p(kTheta, kTheta));
    p.row(kTheta) *= c;
    p.col(kTheta) *= c;
    ++stats_.events["heading_std_bounded"];
    return true;
  } else {
    return false;
  }
}

template <int N>
void UwbEkfT<N>::predictTo(double t) {
  Covariance f, q;
  transition(t - t_, f, q);
  x_ = f * x_;
  if constexpr (kMultitag) x_(kTheta) = wrapAngle(x_(kTheta));
  p_ = f * p_ * f.transpose() + q;
}

template <int N>
double UwbEkfT<N>::rangeModel(const State& x, const Eigen::Vector3d& tag_on_robot,
                              const Eigen::Vector3d& anchor, Jacobian* hj) {
  if constexpr (kMultitag) {
    Eigen::RowVector3d d_pose;
    const double h = uwb::predictRange(Eigen::Vector3d(x(0), x(1), x(kTheta)), tag_on_robot, anchor,
                                       hj ? &d_pose : nullptr);
    if (hj) {
      hj->setZero();
      for (int i = 0; i < 3; ++i) (*hj)(kPoseIndex[i]) = d_pose(i);
    }
    return h;
  } else {
    const Eigen::Vector3d tag(x(0), x(1), tag_on_robot.z());
    const double h = std::max((tag - anchor).norm(), 1e-6);
    if (hj) *hj << (x(0) - anchor.x()) / h, (x(1) - anchor.y()) / h, 0.0, 0.0;
    return h;
  }
}

template <int N>
typename UwbEkfT<N>::RangePrediction UwbEkfT<N>::predictRange(const AcceptedRange& r) {
  RangePrediction pred;
  pred.z = rangeModel(x_, r, &hj_);
  pred.s = (hj_ * p_ * hj_.transpose())(0, 0) + rangeVariance(r);
  return pred;
}

template <int N>
void UwbEkfT<N>::correctWithRange(const AcceptedRange& r, double y, const RangePrediction&) {
  linearCorrect(y, rangeVariance(r));
}

template <int N>
void UwbEkfT<N>::linearCorrect(double y, double r_var, const Eigen::Vector2d* blind) {
  Jacobian h = hj_;
  if (blind) blindAlong(h, *blind);
  kalman::Innovation<1> inn;
  inn.y(0) = y;
  inn.s(0, 0) = (h * p_ * h.transpose())(0, 0) + r_var;
  kalman::josephUpdate<N, 1>(x_, p_, inn, h, Eigen::Matrix<double, 1, 1>(r_var));
}

template <int N, int K>
std::optional<RangeFold> rangeFold(const kalman::PointSet<N, K>& points, const kalman::Vec<N>& x,
                                   const AcceptedRange& r, double depth, double side_sigmas) {
  static_assert(K == 2 * N || K == 2 * N + 1, "a symmetric point set");
  constexpr int first = K - 2 * N;  // the unscented set's mean point comes first
  typename UwbEkfT<N>::Jacobian hj;
  const double at_mean = UwbEkfT<N>::rangeModel(x, r, &hj);
  std::optional<RangeFold> fold;
  double deepest = depth;
  for (int i = first; i < first + N; ++i) {
    const double plus = UwbEkfT<N>::rangeModel(points.x.col(i), r) - at_mean;
    const double minus = UwbEkfT<N>::rangeModel(points.x.col(i + N), r) - at_mean;
    const Eigen::Vector2d along = (points.x.col(i) - x).template head<2>();
    const double fold_depth = std::min(std::abs(plus), std::abs(minus));
    if (plus * minus > 0.0 && fold_depth > deepest && along.norm() > 0.0) {
      deepest = fold_depth;
      fold = RangeFold{along.normalized()};
    }
  }
  if (fold) {
    // The position part of the Jacobian is (tag - anchor)_xy / r: s is the tag's offset along
    // the axis from the point of closest approach.
    const double s = at_mean * hj.template head<2>().dot(fold->axis);
    const double least = std::sqrt(std::max(at_mean * at_mean - s * s, 0.0));
    fold->side_known = at_mean - least > side_sigmas * depth;
  }
  return fold;
}

double predictedPositionStd(const Eigen::Matrix4d& p, double dt, const UwbEkfParams& params) {
  Eigen::Matrix4d f, q;
  constantVelocityModel(std::max(0.0, dt), params.accel_psd, f, q, params.velocity_tau);
  const Eigen::Matrix2d pos = (f * p * f.transpose() + q).topLeftCorner<2, 2>();
  const double half_trace = 0.5 * pos.trace();
  const double det = pos.determinant();
  return std::sqrt(half_trace + std::sqrt(std::max(half_trace * half_trace - det, 0.0)));
}

double readmitTolerance(const UwbEkfParams& params) {
  return std::max(params.readmit_tol, 3.0 * params.front.sigmaValue());
}

template <int N>
PoseEstimate UwbEkfT<N>::output(const Eigen::Vector3d& tag_on_robot) const {
  if constexpr (kMultitag) {
    PoseEstimate e;
    e.t = t_;
    e.pose = Eigen::Vector3d(x_(0), x_(1), x_(kTheta));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) e.covariance(i, j) = p_(kPoseIndex[i], kPoseIndex[j]);
    e.heading_valid = p_(kTheta, kTheta) < kObservedHeadingStd * kObservedHeadingStd;
    return e;
  } else {
    return kalman::tagTrackPose(t_, x_.template head<2>(), p_.template topLeftCorner<2, 2>(),
                                tag_on_robot, heading_.heading());
  }
}

// The first start at the start pose (at rest, position std start_sigma; with several tags,
// heading std start_sigma_yaw), when there is one; otherwise, and after divergence, at the first
// epoch that multilaterates (Gauss-Newton; with several tags, uwb-multitag's on the pose) within
// init_residual.
template <int N>
bool UwbEkfT<N>::initialise(const AcceptedRange& r) {
  const double sp2 = params_.start_sigma * params_.start_sigma;
  if (start_pose_) {
    if constexpr (kMultitag) {
      x_.setZero();
      p_ = Covariance::Identity();  // 1 m/s, 1 rad/s
      x_(0) = start_pose_->x();
      x_(1) = start_pose_->y();
      x_(kTheta) = start_pose_->z();
      const double sy = params_.start_sigma_yaw * M_PI / 180.0;
      p_(0, 0) = p_(1, 1) = sp2;
      p_(kTheta, kTheta) = sy * sy;
    } else {
      x_ << start_pose_->x(), start_pose_->y(), 0.0, 0.0;
      p_ = Eigen::Vector4d(sp2, sp2, 1.0, 1.0).asDiagonal();
    }
    start_pose_.reset();
    t_ = r.measurement.t;
  } else {
    auto epoch = init_epochs_.add(r);
    if (!epoch) return false;
    if constexpr (kMultitag) {
      const UwbMultitagParams gn;  // uwb-multitag's Huber threshold and iterations
      const auto fix = solveMultitag(*epoch, params_.front.sigmaValue(), gn.huber,
                                     gn.max_iterations, std::nullopt);
      if (!fix || fix->rms_residual > params_.init_residual) {
        ++stats_.events["init_fix_refused"];
        return false;
      }
      x_.setZero();
      p_ = Covariance::Identity();
      for (int i = 0; i < 3; ++i) {
        x_(kPoseIndex[i]) = fix->pose(i);
        for (int j = 0; j < 3; ++j) p_(kPoseIndex[i], kPoseIndex[j]) = fix->covariance(i, j);
      }
    } else {
      const auto fix =
          consistentFix(*epoch, params_.front.sigmaValue(), params_.init_residual, stats_);
      if (!fix) return false;
      kalman::initialiseFromFix(*fix, x_, p_);
    }
    t_ = epochTime(*epoch);
  }
  quarantine_.clear();
  initialised_ = true;
  gated_in_a_row_ = 0;
  onStart();
  return true;
}

template <int N>
std::optional<PoseEstimate> UwbEkfT<N>::doProcess(const Event& event) {
  return start_.process(event, learnt_, step_);
}

template <int N>
std::vector<PoseEstimate> UwbEkfT<N>::doFinishAll() {
  return start_.finish(learnt_, step_);
}

template <int N>
std::optional<PoseEstimate> UwbEkfT<N>::doFinish() {
  return newestOfFinishAll();
}

template <int N>
std::optional<PoseEstimate> UwbEkfT<N>::step(const Event& event) {
  auto accepted = acceptRange(event);
  if (!accepted || !correctRange(*accepted, noise_)) return std::nullopt;
  last_innovation_ = std::numeric_limits<double>::quiet_NaN();

  if (initialised_ && params_.reinit_std > 0.0 &&
      predictedPositionStd(p_.template topLeftCorner<4, 4>(), accepted->measurement.t - t_,
                           params_) > params_.reinit_std) {
    ++stats_.events["reinitialised_after_outage"];
    reset();
  }
  if (!initialised_) {
    if (!initialise(*accepted)) return std::nullopt;
    return output(accepted->measurement.tag_on_robot);
  }

  const bool used = updateWithRange(*accepted);
  if constexpr (kMultitag) x_(kTheta) = wrapAngle(x_(kTheta));
  // Every anchor disagreeing with the state for a while means the filter is lost; so does one
  // anchor agreeing while the others disagree beyond readmission (leansOnOneAnchor: a range
  // pins the position to a circle only, and the quarantine never lets the others back; the MRPT
  // demo's uwb-shkf ran 4 m along beacon 2's circle for 5 s, federated-ekf 9 m for 10 s), and a
  // state that rounding has made non-finite.
  gated_in_a_row_ = used ? 0 : gated_in_a_row_ + 1;
  recent_.push_back({accepted->measurement.anchor_id, used, last_innovation_});
  if (recent_.size() > static_cast<size_t>(std::max(params_.max_gated, 0))) recent_.pop_front();
  const bool one_anchor = leansOnOneAnchor();
  if (one_anchor) ++stats_.events["lost_on_one_anchor"];
  if (gated_in_a_row_ >= params_.max_gated || one_anchor || !x_.allFinite() || !p_.allFinite()) {
    ++stats_.resets;
    reset();
    return std::nullopt;
  }
  if (used) {
    trackNearLines(accepted->measurement.anchor_id, accepted->anchor.template head<2>());
  } else if (crossToTheMirror(*accepted)) {
    ++stats_.events["mirrored_across_two_anchors"];
  }
  if constexpr (!kMultitag) heading_.update(x_.template tail<2>());
  return output(accepted->measurement.tag_on_robot);
}

template <int N>
void UwbEkfT<N>::trackNearLines(int anchor, const Eigen::Vector2d& anchor_xy) {
  if constexpr (kMultitag) {
    (void)anchor;
    (void)anchor_xy;
  } else {
    if (anchor_xy_.emplace(anchor, anchor_xy).second) {
      for (const auto& [other, xy] : anchor_xy_) {
        const Eigen::Vector2d along = xy - anchor_xy;
        if (!(along.norm() > 1e-6)) continue;
        lines_.push_back(
            {std::min(anchor, other), std::max(anchor, other), anchor_xy, along.normalized()});
      }
    }
    const Eigen::Vector2d p = x_.template head<2>();
    const Eigen::Matrix2d pp = p_.template topLeftCorner<2, 2>();
    for (auto& l : lines_) {
      // A range of an anchor off a line tells the line's two sides apart.
      if (l.a != anchor && l.b != anchor) l.near = false;
      const Eigen::Vector2d n = l.normal();
      const double d = n.dot(p - l.point);
      if (d * d <= 9.0 * n.dot(pp * n)) l.near = true;
    }
  }
}

// Two anchors fix the tag's position only up to its mirror image across the line through them;
// a third anchor tells the two apart. A filter whose state comes within its uncertainty of that
// line while only those two anchors are used can leave it on the wrong side, and then it keeps
// the two anchors' ranges and refuses the third's for good: the quarantine readmits only ranges
// close to the state (the MRPT demo's federated-ekf, beacon 1 refused for its gross errors,
// crossed the line of beacons 2 and 3 at 305-310 s with a position std of 1.4 m across it, and
// ran 9 m off on the mirror side to the end, refusing beacon 1's good ranges from 320 s on). So
// when
//   - the last max_gated ranges used exactly two anchors A and B,
//   - the state came within 3 sigma of the line AB since an anchor off it was last used,
//   - and the last `readmit` refused ranges, of anchors off AB (C), were each shorter than
//     predicted by more than readmit_tol and within the gate at the state reflected across AB
//     (the range's own variance: the reflection must explain it, not the state's spread),
// the filter moves to that reflection (position and velocity, covariance with them) and lets C
// back. Only short ranges count: NLOS lengthens a range, and the reflection across a line on C's
// far side is farther from C. N = 6 (several tags) is left alone: the tags' geometry tells the
// sides apart.
template <int N>
bool UwbEkfT<N>::crossToTheMirror(const AcceptedRange& r) {
  if constexpr (kMultitag) {
    (void)r;
    return false;
  } else {
    const auto fail = [this] {
      mirror_agreed_ = 0;
      return false;
    };
    const int c = r.measurement.anchor_id;
    if (!(last_innovation_ < -readmitTolerance(params_)) ||
        recent_.size() < static_cast<size_t>(std::max(params_.max_gated, 1)))
      return fail();
    std::optional<int> a, b;  // the two anchors used over the window, C not among them
    for (const auto& e : recent_) {
      if (!e.used || e.anchor == a || e.anchor == b) continue;
      if (e.anchor == c || b) return fail();
      (a ? b : a) = e.anchor;
    }
    if (!b) return fail();
    if (*a > *b) std::swap(*a, *b);
    const auto l = std::find_if(lines_.begin(), lines_.end(),
                                [&](const AnchorLine& x) { return x.a == *a && x.b == *b; });
    if (l == lines_.end() || !l->near) return fail();
    // The reflection across the line: p -> m (p - point) + point, velocities by m.
    const Eigen::Matrix2d m = 2.0 * l->along * l->along.transpose() - Eigen::Matrix2d::Identity();
    Covariance t = Covariance::Identity();
    t.template topLeftCorner<2, 2>() = m;
    t.template block<2, 2>(2, 2) = m;
    State xm = t * x_;
    xm.template head<2>() += l->point - m * l->point;
    const double y = r.measurement.range - rangeModel(xm, r);
    if (!uwb::ChiSquareGate(params_.gate).acceptSquared(y * y / rangeVariance(r))) return fail();
    if (++mirror_agreed_ < std::max(params_.readmit, 1)) return false;
    x_ = xm;
    p_ = t * p_ * t.transpose();
    heading_.setHeading(
        wrapAngle(2.0 * std::atan2(l->along.y(), l->along.x()) - heading_.heading()));
    quarantine_.clear();
    recent_.clear();
    for (auto& x : lines_) x.near = false;
    gated_in_a_row_ = 0;
    mirror_agreed_ = 0;
    onStart();
    return true;
  }
}

template <int N>
bool UwbEkfT<N>::updateWithRange(const AcceptedRange& r) {
  if (r.measurement.t > t_) {
    predictTo(r.measurement.t);
    t_ = r.measurement.t;
  }
  const RangePrediction pred = predictRange(r);
  const double y = r.measurement.range - pred.z;
  const bool in_gate = uwb::ChiSquareGate(params_.gate).acceptSquared(y * y / pred.s);
  if (!admit(r, y, in_gate)) return false;
  correctWithRange(r, y, pred);
  return true;
}

bool RangeQuarantine::admit(const Link& link, double innovation, bool in_gate, int readmit,
                            double tolerance, EstimatorStatistics& stats) {
  auto q = held_.find(link);
  if (!in_gate) {
    countRejection(stats, uwb::toString(uwb::RejectReason::kInnovation), link.first);
    held_[link] = 0;
    return false;
  }
  if (q == held_.end()) return true;
  if (std::abs(innovation) <= tolerance && ++q->second >= readmit) {
    held_.erase(q);
    return true;
  }
  if (std::abs(innovation) > tolerance) q->second = 0;
  countRejection(stats, "quarantine", link.first);
  return false;
}

template <int N>
bool UwbEkfT<N>::admit(const AcceptedRange& r, double innovation, bool in_gate) {
  last_innovation_ = innovation;
  return quarantine_.admit(link(r), innovation, in_gate, params_.readmit, readmitTolerance(params_),
                           stats_);
}

template std::optional<RangeFold> rangeFold(const kalman::PointSet<4, 8>&, const kalman::Vec<4>&,
                                            const AcceptedRange&, double, double);
template std::optional<RangeFold> rangeFold(const kalman::PointSet<6, 12>&, const kalman::Vec<6>&,
                                            const AcceptedRange&, double, double);
template std::optional<RangeFold> rangeFold(const kalman::PointSet<4, 9>&, const kalman::Vec<4>&,
                                            const AcceptedRange&, double, double);
template std::optional<RangeFold> rangeFold(const kalman::PointSet<6, 13>&, const kalman::Vec<6>&,
                                            const AcceptedRange&, double, double);
template class UwbEkfT<4>;
template class UwbEkfT<6>;

}  // namespace uwbloc::loc
