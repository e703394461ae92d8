#include "uwbloc/evaluation/bounds.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <map>

#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::eval {

std::optional<Eigen::Matrix2d> staticCrlb(const std::vector<uwb::Anchor>& anchors,
                                          const Eigen::Vector2d& p, double tag_z, double sigma) {
  Eigen::Matrix2d info = Eigen::Matrix2d::Zero();
  for (const auto& a : anchors) {
    const Eigen::Vector3d d(p.x() - a.position.x(), p.y() - a.position.y(), tag_z - a.position.z());
    const double n = d.norm();
    if (n < 1e-9) continue;
    const Eigen::Vector2d u = d.head<2>() / n;
    info += u * u.transpose() / (sigma * sigma);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(info);
  if (es.eigenvalues()(0) <= 1e-12 * std::max(1.0, es.eigenvalues()(1))) return std::nullopt;
  return info.inverse();
}

std::optional<Eigen::Matrix2d> staticCrlbOfPose(const std::vector<uwb::Anchor>& anchors,
                                                const Eigen::Vector3d& pose,
                                                const std::vector<Eigen::Vector3d>& tags,
                                                double sigma) {
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& tag : tags)
    for (const auto& a : anchors) {
      Eigen::RowVector3d h;
      uwb::predictRange(pose, tag, a.position, &h);
      if (h.allFinite()) info += h.transpose() * h / (sigma * sigma);
    }
  const Eigen::Matrix2d pp = info.topLeftCorner<2, 2>();
  Eigen::Matrix2d position = pp;  // the Schur complement of the heading's block
  if (info(2, 2) > 1e-12 * std::max(1.0, pp.trace()))
    position -= info.topRightCorner<2, 1>() * info.bottomLeftCorner<1, 2>() / info(2, 2);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(position);
  if (es.eigenvalues()(0) <= 1e-12 * std::max(1.0, es.eigenvalues()(1))) return std::nullopt;
  return position.inverse();
}

double BoundSeries::mean(double burn_in) const {
  if (t.empty()) return NAN;
  double sum = 0.0;
  long n = 0;
  for (size_t i = 0; i < t.size(); ++i)
    if (t[i] - t.front() >= burn_in && std::isfinite(position_variance[i])) {
      sum += position_variance[i];
      ++n;
    }
  return n ? sum / static_cast<double>(n) : NAN;
}

namespace {

// Each tag on the robot (its place on the robot, from its first range), in order of tag id.
std::vector<Eigen::Vector3d> tagsOnRobot(const data::Dataset& ds) {
  std::map<int, Eigen::Vector3d> tags;
  for (const auto& e : ds.events)
    if (const auto* r = std::get_if<uwb::Range>(&e); r && r->on_robot)
      tags.emplace(r->tag_id, r->tag_on_robot);
  std::vector<Eigen::Vector3d> out;
  for (const auto& [id, place] : tags) out.push_back(place);
  if (out.empty()) out.push_back(Eigen::Vector3d::Zero());
  return out;
}

}  // namespace

BoundSeries staticCrlbSeries(const data::Dataset& ds, double sigma) {
  BoundSeries out;
  const std::vector<Eigen::Vector3d> tags = tagsOnRobot(ds);
  const Eigen::Vector3d& tag = tags.front();
  for (const auto& g : ds.ground_truth) {
    const auto c = tags.size() > 1 ? staticCrlbOfPose(ds.anchors, g.pose, tags, sigma)
                                   : staticCrlb(ds.anchors, uwb::tagPosition(g.pose, tag).head<2>(),
                                                tag.z(), sigma);
    out.t.push_back(g.t);
    out.position_variance.push_back(c ? c->trace() : NAN);
  }
  return out;
}

BoundSeries posteriorCrlb(const data::Dataset& ds, const data::BoundsSpec& spec) {
  BoundSeries out;
  if (ds.ground_truth.size() < 2) return out;
  const bool cv = spec.motion == "cv";
  const int n = cv ? 4 : 3;
  Eigen::MatrixXd j = Eigen::MatrixXd::Identity(n, n);  // prior: 1 m, 1 m/s (or 1 rad)
  const double var_r = spec.range_sigma * spec.range_sigma;
  double last_t = ds.ground_truth.front().t;
  auto record = [&](double t) {
    const Eigen::MatrixXd p = j.inverse();
    out.t.push_back(t);
    out.position_variance.push_back(p(0, 0) + p(1, 1));
  };
  // Ranges sharing a timestamp form one epoch: the bound is recorded once all are in.
  bool pending = false;
  double pending_t = 0.0;
  for (const auto& e : ds.events) {
    const double t = loc::eventTime(e);
    if (pending && t > pending_t) {
      record(pending_t);
      pending = false;
    }
    if (t < ds.ground_truth.front().t || t > ds.ground_truth.back().t) continue;
    if (cv && t > last_t) {
      // Prediction with the linear CV model: J = (Q + F J^-1 F^T)^-1.
      Eigen::Matrix4d f, q;
      loc::constantVelocityModel(t - last_t, spec.accel_psd, f, q);
      j = (q + f * j.inverse() * f.transpose()).inverse();
      last_t = t;
    }
    if (const auto* o = std::get_if<loc::OdometryIncrement>(&e); o && !cv) {
      const auto truth = interpolateGroundTruth(ds.ground_truth, t, 2.0);
      if (!truth) continue;
      // x_{k+1} = x_k (+) u: F = d/dx, G = d/du at the true pose, Q = G diag(sigma_u^2) G^T.
      const double th = truth->z(), c = std::cos(th), s = std::sin(th);
      const Eigen::Vector3d& u = o->delta;
      Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
      f(0, 2) = -s * u.x() - c * u.y();
      f(1, 2) = c * u.x() - s * u.y();
      Eigen::Matrix3d g;
      g << c, -s, 0, s, c, 0, 0, 0, 1;
      const double dist = u.head<2>().norm();
      const double sxy = std::max(spec.odom_sigma_xy_per_m * dist, 1e-6);
      const double sth = std::max(
          spec.odom_sigma_theta_per_rad * std::abs(u.z()) + spec.odom_sigma_theta_per_m * dist,
          1e-6);
      const Eigen::Matrix3d q =
          g * Eigen::Vector3d(sxy * sxy, sxy * sxy, sth * sth).asDiagonal() * g.transpose();
      j = (q + f * j.inverse() * f.transpose()).inverse();
      continue;
    }
    const auto* r = std::get_if<uwb::Range>(&e);
    if (!r || !r->on_robot) continue;
    const uwb::Anchor* a = uwb::findAnchor(ds.anchors, r->anchor_id);
    const auto truth = interpolateGroundTruth(ds.ground_truth, t, 2.0);
    if (!a || !truth) continue;
    // Measurement information H^T H / sigma^2 at the true pose.
    Eigen::RowVector3d hp;
    uwb::predictRange(*truth, r->tag_on_robot, a->position, &hp);
    Eigen::RowVectorXd h = Eigen::RowVectorXd::Zero(n);
    h(0) = hp(0);
    h(1) = hp(1);
    if (!cv) h(2) = hp(2);
    j += h.transpose() * h / var_r;
    pending = true;
    pending_t = t;
  }
  if (pending) record(pending_t);
  return out;
}

}  // namespace uwbloc::eval
