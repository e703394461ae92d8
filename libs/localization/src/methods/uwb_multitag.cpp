#include "uwbloc/localization/methods/uwb_multitag.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <map>

#include "uwbloc/uwb/pose2.hpp"
#include "uwbloc/uwb/range_model.hpp"
#include "uwbloc/uwb/rigid_fit.hpp"

namespace uwbloc::loc {

namespace {

// Weighted Gauss-Newton with Huber weights; `fix_heading` solves for x, y alone.
std::optional<MultitagFix> gaussNewton(const std::vector<AcceptedRange>& epoch, double sigma,
                                       double huber, int max_iterations, Eigen::Vector3d pose,
                                       bool fix_heading) {
  // The normal matrix, with the heading's row and column replaced by identity when it is held:
  // one fixed-size solve serves both cases (no allocation per iteration).
  auto normal = [fix_heading](Eigen::Matrix3d h) {
    if (fix_heading) {
      h.row(2).setZero();
      h.col(2).setZero();
      h(2, 2) = 1.0;
    }
    return Eigen::LDLT<Eigen::Matrix3d>(h);
  };
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  double cost = 0.0;
  for (int it = 0; it <= max_iterations; ++it) {
    h.setZero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    cost = 0.0;
    const double c = std::cos(pose.z()), s = std::sin(pose.z());
    for (const auto& r : epoch) {
      const Eigen::Vector3d& l = r.measurement.tag_on_robot;
      const Eigen::Vector3d tag(pose.x() + c * l.x() - s * l.y(), pose.y() + s * l.x() + c * l.y(),
                                l.z());
      const Eigen::Vector3d d = tag - r.anchor;
      const double dist = std::max(d.norm(), 1e-6);
      const double sd = sigma * std::sqrt(r.variance_scale);
      const double e = (r.measurement.range - dist) / sd;
      const double w = std::abs(e) <= huber ? 1.0 : huber / std::abs(e);
      // d(dist)/d(x, y, theta); the tag moves with theta by R'(theta) l.
      const Eigen::Vector3d j(
          d.x() / dist, d.y() / dist,
          (d.x() * (-s * l.x() - c * l.y()) + d.y() * (c * l.x() - s * l.y())) / dist);
      const Eigen::Vector3d js = j / sd;
      h += w * js * js.transpose();
      g += w * js * e;
      cost += w * e * e;
    }
    if (it == max_iterations) break;
    if (fix_heading) g.z() = 0.0;
    const auto ldlt = normal(h);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return std::nullopt;
    const Eigen::Vector3d step = ldlt.solve(g);
    if (!step.allFinite()) return std::nullopt;
    pose += step;
    pose.z() = wrapAngle(pose.z());
    if (step.head<2>().norm() < 1e-5 && std::abs(step.z()) < 1e-6) break;
  }
  if (!pose.allFinite()) return std::nullopt;
  MultitagFix fix;
  fix.pose = pose;
  fix.rms_residual = sigma * std::sqrt(cost / static_cast<double>(epoch.size()));
  const auto ldlt = normal(h);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return std::nullopt;
  fix.covariance = ldlt.solve(Eigen::Matrix3d::Identity());
  if (fix_heading) fix.covariance(2, 2) = M_PI * M_PI;
  return fix;
}

// Closed-form start: multilaterate each tag with three ranges or more, then fit the lever arms
// to those points (2D Procrustes). Nothing when no tag can be multilaterated.
std::optional<Eigen::Vector3d> closedFormStart(const std::vector<AcceptedRange>& epoch,
                                               double sigma, int* solved_tags) {
  std::map<int, std::vector<const AcceptedRange*>> by_tag;
  for (const auto& r : epoch) by_tag[r.measurement.tag_id].push_back(&r);
  std::vector<uwb::BodyPoint> points;
  for (const auto& [tag, ranges] : by_tag) {
    if (ranges.size() < 3) continue;
    std::vector<uwb::PlanarRange> planar;
    for (const auto* r : ranges) planar.push_back({r->anchor.head<2>(), r->planar, sigma});
    const uwb::Fix fix = uwb::solveGaussNewton(planar);
    if (!fix.ok()) continue;
    points.push_back({ranges.front()->measurement.tag_on_robot.head<2>(), fix.position});
  }
  *solved_tags = static_cast<int>(points.size());
  if (points.empty()) return std::nullopt;
  if (points.size() == 1)
    return Eigen::Vector3d(points[0].measured.x(), points[0].measured.y(), 0.0);
  return uwb::procrustes2d(points, std::vector<double>(points.size(), 1.0));
}

}  // namespace

std::optional<MultitagFix> solveMultitag(const std::vector<AcceptedRange>& epoch, double sigma,
                                         double huber, int max_iterations,
                                         const std::optional<Eigen::Vector3d>& start) {
  if (epoch.size() < 3) return std::nullopt;
  std::map<int, int> tags;
  for (const auto& r : epoch) ++tags[r.measurement.tag_id];
  const int n_tags = static_cast<int>(tags.size());
  const bool fix_heading = n_tags < 2;
  std::optional<MultitagFix> best;
  auto keep = [&](std::optional<MultitagFix> f) {
    if (f && (!best || f->rms_residual < best->rms_residual)) best = f;
  };
  if (start) {
    keep(gaussNewton(epoch, sigma, huber, max_iterations, *start, fix_heading));
  } else {
    int solved = 0;
    const auto cf = closedFormStart(epoch, sigma, &solved);
    if (!cf) return std::nullopt;
    if (solved >= 2 || fix_heading) {
      keep(gaussNewton(epoch, sigma, huber, max_iterations, *cf, fix_heading));
    } else {
      // One tag multilaterated: its point, with the heading unknown; try four.
      for (int k = 0; k < 4; ++k) {
        const double th = k * M_PI / 2;
        const Eigen::Vector2d tag_point = cf->head<2>();
        const Eigen::Vector2d l = epoch.front().measurement.tag_on_robot.head<2>();
        const Eigen::Vector2d p = tag_point - rotation(th) * l;
        keep(gaussNewton(epoch, sigma, huber, max_iterations, {p.x(), p.y(), th}, false));
      }
    }
  }
  if (best) best->tags = n_tags;
  return best;
}

UwbMultitag::UwbMultitag(const UwbMultitagParams& params, const EstimatorContext& context)
    : EpochUwbEstimator(params.front, context, params.epoch_window, TagUse::kAll, params.learning),
      params_(params) {
  // Its Gauss-Newton starts from the last pose, and a wrong range pulls the fix only part of the
  // way, inside the track's gate: the range itself must agree (MRPT demo 0.377 -> 0.236 m).
  checkEveryRange();
}

void UwbMultitag::noteVariance(const MultitagFix& fix, size_t ranges) {
  if (ranges <= 3) return;
  const double v = fix.rms_residual * fix.rms_residual * static_cast<double>(ranges) /
                   static_cast<double>(ranges - 3);
  variances_.add(v);
}

double UwbMultitag::rangeVariance() {
  const double sigma = rangeSigma();
  if (variances_.size() < 5) return sigma * sigma;
  return std::max(variances_.median(), 1e-6);
}

bool UwbMultitag::filter(double t, const MultitagFix& fix, const Eigen::Matrix3d& r) {
  if (!filtering_ || t - t_ > params_.restart_after) {
    x_.setZero();
    x_.head<3>() = fix.pose;
    p_.setZero();
    p_.topLeftCorner<3, 3>() = r;
    p_.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity();  // 1 m/s, 1 rad/s
    t_ = t;
    filtering_ = true;
    gated_in_a_row_ = 0;
    return true;
  }
  const double dt = std::max(0.0, t - t_);
  t_ = t;
  Eigen::Matrix<double, 6, 6> f = Eigen::Matrix<double, 6, 6>::Identity();
  f.topRightCorner<3, 3>() = dt * Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 6, 6> q = Eigen::Matrix<double, 6, 6>::Zero();
  const Eigen::Vector3d psd(params_.accel_psd, params_.accel_psd, params_.yaw_accel_psd);
  for (int i = 0; i < 3; ++i) {
    q(i, i) = psd(i) * dt * dt * dt / 3.0;
    q(i, i + 3) = q(i + 3, i) = psd(i) * dt * dt / 2.0;
    q(i + 3, i + 3) = psd(i) * dt;
  }
  x_ = f * x_;
  x_(2) = wrapAngle(x_(2));
  p_ = f * p_ * f.transpose() + q;
  Eigen::Vector3d innovation = fix.pose - x_.head<3>();
  innovation.z() = wrapAngle(innovation.z());
  const Eigen::Matrix3d s = p_.topLeftCorner<3, 3>() + r;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(s);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
  if (innovation.dot(ldlt.solve(innovation)) > params_.gate) {
    if (++gated_in_a_row_ >= params_.max_gated) {
      ++stats_.resets;
      filtering_ = false;
      return filter(t, fix, r);
    }
    return false;
  }
  gated_in_a_row_ = 0;
  const Eigen::Matrix<double, 6, 3> k = p_.leftCols<3>() * ldlt.solve(Eigen::Matrix3d::Identity());
  x_ += k * innovation;
  x_(2) = wrapAngle(x_(2));
  const Eigen::Matrix<double, 6, 6> ikh =
      Eigen::Matrix<double, 6, 6>::Identity() - k * Eigen::Matrix<double, 3, 6>::Identity();
  p_ = ikh * p_ * ikh.transpose() + k * r * k.transpose();
  return true;
}

std::optional<MultitagFix> UwbMultitag::continuityChecked(const std::vector<AcceptedRange>& epoch,
                                                          const MultitagFix& fix, bool* replaced) {
  const Eigen::Vector2d lever =
      rotation(fix.pose.z()) * epoch.front().measurement.tag_on_robot.head<2>();
  // The fix's covariance and the ranges' std as the epochs' residuals show them.
  const double variance = rangeVariance(), sigma = rangeSigma();
  const auto planar = toPlanar(epoch, std::sqrt(variance));
  uwb::Fix tag;
  tag.status = uwb::FixStatus::kOk;
  tag.position = fix.pose.head<2>() + lever;
  tag.covariance = fix.covariance.topLeftCorner<2, 2>() * (variance / (sigma * sigma));
  std::optional<Eigen::Vector2d> seed;
  if (initialPose()) seed = initialPose()->head<2>();
  const auto checked = EpochUwbEstimator::continuityChecked(
      epoch, tag, planar, [](const auto& subset) { return uwb::solveGaussNewton(subset); }, -lever,
      seed);
  *replaced = checked.outcome == Continuity::kExcluded;
  if (!checked.fix) return std::nullopt;
  if (!*replaced) return fix;
  MultitagFix out = fix;
  out.pose.head<2>() = checked.fix->position - lever;
  out.covariance.topLeftCorner<2, 2>() = checked.fix->covariance * (sigma * sigma / variance);
  out.rms_residual = checked.fix->residual_norm;
  return out;
}

std::optional<PoseEstimate> UwbMultitag::onEpoch(const std::vector<AcceptedRange>& epoch) {
  const double t = epochTime(epoch);
  std::optional<Eigen::Vector3d> start;
  if (last_ && t - last_t_ <= params_.restart_after) start = last_;
  auto fix = solveMultitag(epoch, rangeSigma(), params_.huber, params_.max_iterations, start);
  if (!fix) {
    countRejection(epoch.size() < 3 ? "epoch_too_few_ranges" : "epoch_no_solution");
    return std::nullopt;
  }
  // A replaced fix leaves ranges out: its residual does not feed the range variance.
  bool replaced = false;
  if (params_.continuity && fix->tags == 1) {
    fix = continuityChecked(epoch, *fix, &replaced);
    if (!fix) return std::nullopt;
  }
  if (fix->tags >= 2) heading_seen_ = true;
  last_ = fix->pose;
  last_t_ = t;
  if (!replaced) noteVariance(*fix, epoch.size());
  const Eigen::Matrix3d r = fix->covariance * (rangeVariance() / (rangeSigma() * rangeSigma()));
  PoseEstimate e;
  e.t = t;
  e.heading_valid = heading_seen_;
  if (!params_.smooth) {
    e.pose = fix->pose;
    e.covariance = r;
    return e;
  }
  if (!filter(t, *fix, r)) {
    countRejection("fix_gated");
    return std::nullopt;
  }
  e.pose = x_.head<3>();
  e.covariance = p_.topLeftCorner<3, 3>();
  return e;
}

}  // namespace uwbloc::loc
