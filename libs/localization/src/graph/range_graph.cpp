#include "uwbloc/localization/graph/range_graph.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>

#include "cost_functions.hpp"
#include "uwbloc/localization/graph/marginals.hpp"
#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc::graph {

RangeGraph::RangeGraph() = default;
RangeGraph::~RangeGraph() = default;
RangeGraph::RangeGraph(RangeGraph&&) noexcept = default;
RangeGraph& RangeGraph::operator=(RangeGraph&&) noexcept = default;

void RangeGraph::holdPose(int pose) {
  problem_->SetParameterBlockConstant(poses_[static_cast<size_t>(pose)].data());
}

void RangeGraph::holdRangeModel() {
  for (auto& b : biases_) problem_->SetParameterBlockConstant(&b);
  problem_->SetParameterBlockConstant(&scale_);
}

int RangeGraph::addPose(const Eigen::Vector3d& initial) {
  poses_.push_back(initial);
  return static_cast<int>(poses_.size()) - 1;
}

void RangeGraph::setAnchors(const std::vector<uwb::Anchor>& anchors) {
  anchors_ = anchors;
  anchor_prior_.clear();
  for (const auto& a : anchors) anchor_prior_.push_back(a.position);
  biases_.assign(anchors.size(), 0.0);
}

void RangeGraph::addOdometry(int from, int to, const Eigen::Vector3d& delta,
                             const std::optional<Eigen::Vector3d>& sigma) {
  std::optional<Eigen::Matrix3d> sqrt_information;
  if (sigma) sqrt_information = Eigen::Matrix3d(sigma->cwiseInverse().asDiagonal());
  odometry_.push_back({from, to, delta, sqrt_information});
}

void RangeGraph::addRelativePose(int from, int to, const Eigen::Vector3d& delta,
                                 const Eigen::Matrix3d& information) {
  // Omega = L^T L with L upper triangular: the transpose of the Cholesky factor.
  const Eigen::LLT<Eigen::Matrix3d> llt(0.5 * (information + information.transpose()));
  if (llt.info() != Eigen::Success || !information.allFinite())
    throw std::invalid_argument("RangeGraph: relative-pose information is not positive definite");
  odometry_.push_back({from, to, delta, Eigen::Matrix3d(llt.matrixU())});
}

void RangeGraph::addRange(int pose, int anchor_id, double range, const Eigen::Vector3d& tag,
                          double variance_scale, int tag_id) {
  for (size_t i = 0; i < anchors_.size(); ++i)
    if (anchors_[i].id == anchor_id) {
      ranges_.push_back({pose, static_cast<int>(i), range, tag, variance_scale, tag_id});
      return;
    }
  throw std::invalid_argument("RangeGraph: unknown anchor " + std::to_string(anchor_id));
}

void RangeGraph::addConstantVelocity(int a, int b, int c, double dt1, double dt2) {
  if (!(dt1 > 0.0) || !(dt2 > 0.0))
    throw std::invalid_argument("RangeGraph: a constant-velocity edge needs positive time steps");
  constant_velocity_.push_back({a, b, c, dt1, dt2});
}

void RangeGraph::addPosePrior(int pose, const Eigen::Vector3d& mean, const Eigen::Vector3d& sigma) {
  priors_.push_back({pose, mean, sigma});
}

int RangeGraph::addLandmark(const Eigen::Vector2d& initial) {
  landmarks_.push_back(initial);
  return static_cast<int>(landmarks_.size()) - 1;
}

void RangeGraph::addLandmarkObservation(int pose, int landmark, const Eigen::Vector2d& z,
                                        double sigma) {
  landmark_obs_.push_back({pose, landmark, z, sigma});
}

std::optional<Eigen::Matrix3d> RangeGraph::poseCovariance(int pose) {
  if (!problem_) return std::nullopt;
  double* block = poses_[static_cast<size_t>(pose)].data();
  if (problem_->IsParameterBlockConstant(block)) return Eigen::Matrix3d::Zero();
  ceres::Covariance::Options options;
  ceres::Covariance covariance(options);
  const std::vector<std::pair<const double*, const double*>> blocks{{block, block}};
  if (!covariance.Compute(blocks, problem_.get())) return std::nullopt;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c;
  if (!covariance.GetCovarianceBlockInTangentSpace(block, block, c.data())) return std::nullopt;
  return Eigen::Matrix3d(c);
}

std::vector<size_t> RangeGraph::freePoses(std::vector<double*>& blocks) {
  std::vector<size_t> index;
  for (size_t i = 0; i < poses_.size(); ++i)
    if (!problem_->IsParameterBlockConstant(poses_[i].data())) {
      blocks.push_back(poses_[i].data());
      index.push_back(i);
    }
  return index;
}

std::vector<Eigen::Matrix3d> RangeGraph::poseCovariances() {
  std::vector<Eigen::Matrix3d> out(poses_.size(), Eigen::Matrix3d::Zero());
  if (!problem_) return {};
  std::vector<double*> blocks;
  const std::vector<size_t> index = freePoses(blocks);
  const auto marginals = marginalCovariances(*problem_, blocks);
  if (!marginals) return {};
  for (size_t k = 0; k < index.size(); ++k) out[index[k]] = (*marginals)[k];
  return out;
}

void RangeGraph::build(const RangeGraphParams& params) {
  params_ = params;
  problem_ = std::make_unique<ceres::Problem>();
  ceres::Problem& p = *problem_;
  for (auto& pose : poses_)
    p.AddParameterBlock(pose.data(), 3, new ceres::AutoDiffManifold<PosePlus, 3, 3>);
  // An anchor's height is held: a planar robot's ranges barely observe it, and a free z trades
  // off against x, y (heights are easy to survey).
  for (auto& a : anchors_)
    p.AddParameterBlock(a.position.data(), 3, new ceres::SubsetManifold(3, {2}));
  for (auto& b : biases_) p.AddParameterBlock(&b, 1);
  p.AddParameterBlock(&scale_, 1);
  // Under a mixture, one residual shape per variance scale and NLOS prior (to the nearest
  // 1 / kPriorLevels; most ranges share a few).
  constexpr double kPriorLevels = 20.0;
  std::map<std::pair<double, long>, std::shared_ptr<const MixtureResidual>> shapes;
  for (size_t k = 0; k < ranges_.size(); ++k) {
    const auto& r = ranges_[k];
    if (r.anchor == params_.left_out_anchor) continue;
    if (params_.range_mixture) {
      const long level = nlos_prior_.empty() ? -1 : std::lround(nlos_prior_[k] * kPriorLevels);
      auto& shape = shapes[{r.variance_scale, level}];
      if (!shape) {
        RangeMixture m = *params_.range_mixture;
        if (level >= 0) m = m.withNlosFraction(static_cast<double>(level) / kPriorLevels);
        shape = std::make_shared<const MixtureResidual>(
            m, params_.range_mixture->sigma * std::sqrt(r.variance_scale));
      }
      p.AddResidualBlock(MixtureRangeCost::Create(r.range, r.tag, shape), nullptr,
                         poses_[static_cast<size_t>(r.pose)].data(),
                         anchors_[static_cast<size_t>(r.anchor)].position.data(),
                         &biases_[biasIndex(r.anchor)], &scale_);
      continue;
    }
    ceres::LossFunction* loss = nullptr;
    if (params_.loss == RobustLoss::kHuber)
      loss = new ceres::HuberLoss(params_.loss_scale);
    else if (params_.loss == RobustLoss::kCauchy)
      loss = new ceres::CauchyLoss(params_.loss_scale);
    p.AddResidualBlock(
        RangeCost::Create(r.range, r.tag, params_.range_sigma * std::sqrt(r.variance_scale)), loss,
        poses_[static_cast<size_t>(r.pose)].data(),
        anchors_[static_cast<size_t>(r.anchor)].position.data(), &biases_[biasIndex(r.anchor)],
        &scale_);
  }
  if (params_.estimate_scale && !ranges_.empty()) {
    p.AddResidualBlock(
        PriorCost<1>::Create(Eigen::Matrix<double, 1, 1>::Zero(),
                             Eigen::Matrix<double, 1, 1>::Constant(params_.scale_prior_sigma)),
        nullptr, &scale_);
  } else {
    scale_ = 0.0;  // a solve with a scale may have left a value
    p.SetParameterBlockConstant(&scale_);
  }
  const Eigen::Matrix3d default_sqrt_information =
      params_.odometry_sigma.cwiseInverse().asDiagonal();
  const double odometry_weight = 1.0 / params_.odometry_sigma_factor;
  for (const auto& o : odometry_)
    p.AddResidualBlock(
        RelativePoseCost::Create(
            o.delta, Eigen::Matrix3d(odometry_weight *
                                     o.sqrt_information.value_or(default_sqrt_information))),
        nullptr, poses_[static_cast<size_t>(o.from)].data(),
        poses_[static_cast<size_t>(o.to)].data());
  for (const auto& e : constant_velocity_)
    p.AddResidualBlock(ConstantVelocityCost::Create(e.dt1, e.dt2, params_.accel_psd), nullptr,
                       poses_[static_cast<size_t>(e.a)].data(),
                       poses_[static_cast<size_t>(e.b)].data(),
                       poses_[static_cast<size_t>(e.c)].data());
  for (auto& l : landmarks_) p.AddParameterBlock(l.data(), 2);
  for (const auto& o : landmark_obs_)
    p.AddResidualBlock(LandmarkCost::Create(o.z, o.sigma), nullptr,
                       poses_[static_cast<size_t>(o.pose)].data(),
                       landmarks_[static_cast<size_t>(o.landmark)].data());
  for (const auto& pr : priors_)
    p.AddResidualBlock(PosePriorCost::Create(pr.mean, pr.sigma), nullptr,
                       poses_[static_cast<size_t>(pr.pose)].data());
  for (size_t i = 0; i < anchors_.size(); ++i) {
    if (params_.estimate_anchors) {
      p.AddResidualBlock(PriorCost<3>::Create(anchor_prior_[i], Eigen::Vector3d::Constant(
                                                                    params_.anchor_prior_sigma)),
                         nullptr, anchors_[i].position.data());
    } else {
      p.SetParameterBlockConstant(anchors_[i].position.data());
    }
    if (params_.estimate_bias && (!params_.common_bias || i == 0)) {
      p.AddResidualBlock(
          PriorCost<1>::Create(Eigen::Matrix<double, 1, 1>::Zero(),
                               Eigen::Matrix<double, 1, 1>::Constant(params_.bias_prior_sigma)),
          nullptr, &biases_[i]);
    } else {
      biases_[i] = 0.0;  // a solve with biases may have left values
      p.SetParameterBlockConstant(&biases_[i]);
    }
  }
  // Gauge: fixed anchors fix the frame. Ranges alone do not change when every anchor and pose
  // is moved or rotated together, and the anchor priors only fix that motion to within their
  // own error; so with estimated anchors the first anchor and the first pose are held: two
  // points fix the translation and the rotation.
  if (params_.estimate_anchors && !poses_.empty()) {
    p.SetParameterBlockConstant(poses_.front().data());
    if (!anchors_.empty()) p.SetParameterBlockConstant(anchors_.front().position.data());
  }
}

void RangeGraph::setNlosPriors(std::vector<double> priors) {
  if (!priors.empty() && priors.size() != ranges_.size())
    throw std::invalid_argument("RangeGraph::setNlosPriors: " + std::to_string(priors.size()) +
                                " priors for " + std::to_string(ranges_.size()) + " ranges");
  nlos_prior_ = std::move(priors);
}

std::vector<RangeGraph::RangeEdge> RangeGraph::rangeEdges() const {
  std::vector<RangeEdge> out;
  out.reserve(ranges_.size());
  for (const auto& r : ranges_)
    out.push_back({anchors_[static_cast<size_t>(r.anchor)].id, r.tag_id, r.variance_scale});
  return out;
}

GraphSolution RangeGraph::solve() {
  if (!problem_) throw std::logic_error("RangeGraph::solve() before build()");
  ceres::Solver::Options options;
  options.max_num_iterations = params_.max_iterations;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.num_threads = params_.threads > 0
                            ? params_.threads
                            : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem_.get(), &summary);
  GraphSolution out;
  out.usable = summary.IsSolutionUsable();
  out.iterations = static_cast<int>(summary.iterations.size());
  out.initial_cost = summary.initial_cost;
  out.final_cost = summary.final_cost;
  out.report = summary.BriefReport();
  return out;
}

double RangeGraph::rangeResidual(const Range& r, Eigen::Vector3d* gradient,
                                 double* distance) const {
  const Eigen::Vector3d& x = poses_[static_cast<size_t>(r.pose)];
  const Eigen::Vector3d& a = anchors_[static_cast<size_t>(r.anchor)].position;
  const double c = std::cos(x.z()), s = std::sin(x.z());
  const Eigen::Vector3d d(x.x() + c * r.tag.x() - s * r.tag.y() - a.x(),
                          x.y() + s * r.tag.x() + c * r.tag.y() - a.y(), r.tag.z() - a.z());
  const double dist = std::max(d.norm(), 1e-9);
  if (gradient) {
    // d(dist)/d(x, y, theta); the residual's gradient is its negative.
    const double dtheta =
        d.x() * (-s * r.tag.x() - c * r.tag.y()) + d.y() * (c * r.tag.x() - s * r.tag.y());
    *gradient = -(1.0 + scale_) * Eigen::Vector3d(d.x(), d.y(), dtheta) / dist;
  }
  if (distance) *distance = dist;
  return r.range - (1.0 + scale_) * dist - biases_[biasIndex(r.anchor)];
}

double RangeGraph::lossWeight(double whitened) const {
  const double u = whitened / params_.loss_scale;
  if (params_.loss == RobustLoss::kCauchy) return 1.0 / (1.0 + u * u);
  if (params_.loss == RobustLoss::kHuber) return std::abs(u) <= 1.0 ? 1.0 : 1.0 / std::abs(u);
  return 1.0;
}

double RangeGraph::lossConsistency() const {
  // E[w(z) z^2] / E[w(z)] for z ~ N(0, 1), by the midpoint rule over +-10: the factor by which
  // the robust weights shrink a Gaussian's variance estimate (1 without a loss).
  double num = 0.0, den = 0.0;
  const double h = 1e-3;
  for (double z = -10.0 + 0.5 * h; z < 10.0; z += h) {
    const double pdf = std::exp(-0.5 * z * z), w = lossWeight(z);
    num += w * z * z * pdf;
    den += w * pdf;
  }
  return num / den;
}

std::optional<double> RangeGraph::estimateRangeSigma() {
  return estimateVarianceComponents().range_sigma;
}

RangeGraph::VarianceComponents RangeGraph::estimateVarianceComponents() {
  VarianceComponents out;
  if (!problem_ || ranges_.empty()) return out;
  ceres::Problem& p = *problem_;
  // The marginal covariances of the free poses and biases (marginals.hpp).
  std::vector<double*> blocks;
  const std::vector<size_t> pose_index = freePoses(blocks);
  int free_bias = 0;
  for (auto& b : biases_)
    if (!p.IsParameterBlockConstant(&b)) {
      blocks.push_back(&b);
      ++free_bias;
    }
  const bool free_scale = !p.IsParameterBlockConstant(&scale_);
  if (free_scale) blocks.push_back(&scale_);
  const auto marginals = marginalCovariances(p, blocks);
  if (!marginals) return out;
  std::vector<Eigen::Matrix3d> pose_cov(poses_.size(), Eigen::Matrix3d::Zero());
  for (size_t k = 0; k < pose_index.size(); ++k) pose_cov[pose_index[k]] = (*marginals)[k];
  // A free bias or scale takes about one leverage from the range edges, less its prior's share.
  double bias_prior_leverage = 0.0;
  for (size_t k = pose_index.size(); k < pose_index.size() + static_cast<size_t>(free_bias); ++k)
    bias_prior_leverage +=
        (*marginals)[k](0, 0) / (params_.bias_prior_sigma * params_.bias_prior_sigma);
  if (free_scale) {
    ++free_bias;
    bias_prior_leverage +=
        marginals->back()(0, 0) / (params_.scale_prior_sigma * params_.scale_prior_sigma);
  }
  // The range group. Leverage of one edge: w J Sigma J^T / sigma^2 (pose part); a free bias adds
  // about one leverage to its anchor's edges (less its prior's share).
  const double sigma = params_.range_sigma;
  double weighted_sq = 0.0, redundancy = 0.0, pose_leverage = 0.0;
  for (const auto& r : ranges_) {
    if (r.anchor == params_.left_out_anchor) continue;
    Eigen::Vector3d g;
    // Normalised by the range's own variance scale (1 unless an NLOS model doubted it).
    const double root = std::sqrt(r.variance_scale);
    const double e = rangeResidual(r, &g) / root;
    g /= root;
    const double w = lossWeight(e / sigma);
    const double h = w * g.dot(pose_cov[static_cast<size_t>(r.pose)] * g) / (sigma * sigma);
    weighted_sq += w * e * e;
    redundancy += w - h;
    pose_leverage += h;
  }
  redundancy -= free_bias - bias_prior_leverage;
  if (redundancy > 1.0) {
    const double sigma_new = std::sqrt(weighted_sq / (redundancy * lossConsistency()));
    if (std::isfinite(sigma_new)) out.range_sigma = sigma_new;
  }
  // The constant-velocity group: the free poses' parameters less the leverage the ranges and
  // the pose priors take of them (a bias's or the scale's parameter goes to its ranges and its
  // prior) is theirs.
  if (constant_velocity_.empty() || !odometry_.empty() || !landmark_obs_.empty() ||
      params_.estimate_anchors)
    return out;
  for (const auto& pr : priors_)
    for (int i = 0; i < 3; ++i)
      pose_leverage += pose_cov[static_cast<size_t>(pr.pose)](i, i) / (pr.sigma(i) * pr.sigma(i));
  double cv_sq = 0.0;
  for (const auto& e : constant_velocity_) {
    const Eigen::Vector2d change = (poses_[static_cast<size_t>(e.c)].head<2>() -
                                    poses_[static_cast<size_t>(e.b)].head<2>()) /
                                       e.dt2 -
                                   (poses_[static_cast<size_t>(e.b)].head<2>() -
                                    poses_[static_cast<size_t>(e.a)].head<2>()) /
                                       e.dt1;
    cv_sq += change.squaredNorm() / (0.5 * (e.dt1 + e.dt2));  // whitened at q = 1
  }
  const double cv_redundancy =
      2.0 * static_cast<double>(constant_velocity_.size()) -
      (3.0 * static_cast<double>(pose_index.size()) - pose_leverage);
  if (cv_redundancy > 1.0 && std::isfinite(cv_sq)) out.accel_psd = cv_sq / cv_redundancy;
  return out;
}

void RangeGraph::restore(const Values& v) {
  if (v.poses.size() != poses_.size() || v.anchors.size() != anchors_.size() ||
      v.biases.size() != biases_.size() || v.landmarks.size() != landmarks_.size())
    throw std::logic_error("RangeGraph::restore() with the values of another graph");
  // In place: the Ceres problem holds pointers to these vertices.
  std::copy(v.poses.begin(), v.poses.end(), poses_.begin());
  for (size_t i = 0; i < anchors_.size(); ++i) anchors_[i].position = v.anchors[i].position;
  std::copy(v.biases.begin(), v.biases.end(), biases_.begin());
  scale_ = v.scale;
  std::copy(v.landmarks.begin(), v.landmarks.end(), landmarks_.begin());
}

ScaleEvidence RangeGraph::scaleEvidence() const {
  ScaleEvidence out;
  if (ranges_.empty()) return out;
  std::vector<double> e(ranges_.size()), d(ranges_.size());
  for (size_t i = 0; i < ranges_.size(); ++i) e[i] = rangeResidual(ranges_[i], nullptr, &d[i]);
  // The robust centre and spread of all residuals, to leave out the NLOS ones.
  const double centre = medianOf(e);
  std::vector<double> deviation(e.size());
  for (size_t i = 0; i < e.size(); ++i) deviation[i] = std::abs(e[i] - centre);
  const double spread = std::max(1.4826 * medianOf(std::move(deviation)), 1e-6);
  auto kept = [&](size_t i) { return std::abs(e[i] - centre) <= 3.0 * spread; };
  // The slope within anchors: each anchor's residuals and distances are centred on their own
  // means, so that a bias (per anchor, or on every anchor alike) adds nothing to it.
  const size_t half = ranges_.size() / 2;
  const size_t anchors = anchors_.size();
  for (int h = 0; h < 3; ++h) {
    const size_t begin = h == 2 ? half : 0, end = h == 1 ? half : ranges_.size();
    std::vector<double> n(anchors, 0.0), sd(anchors, 0.0), se(anchors, 0.0);
    for (size_t i = begin; i < end; ++i)
      if (kept(i)) {
        const auto a = static_cast<size_t>(ranges_[i].anchor);
        n[a] += 1, sd[a] += d[i], se[a] += e[i];
      }
    double sdd = 0, sde = 0, see = 0, count = 0;
    for (size_t i = begin; i < end; ++i)
      if (kept(i)) {
        const auto a = static_cast<size_t>(ranges_[i].anchor);
        const double dd = d[i] - sd[a] / n[a], de = e[i] - se[a] / n[a];
        sdd += dd * dd, sde += dd * de, see += de * de, count += 1;
      }
    if (count < 3 || !(sdd > 0)) continue;
    const double slope = sde / sdd;
    double ss = 0;
    for (size_t i = begin; i < end; ++i)
      if (kept(i)) {
        const auto a = static_cast<size_t>(ranges_[i].anchor);
        const double r = (e[i] - se[a] / n[a]) - slope * (d[i] - sd[a] / n[a]);
        ss += r * r;
      }
    double groups = 0;
    for (double k : n) groups += k > 0;
    out.explained[h] = see > 0 ? slope * slope * sdd / see : 0.0;
    out.slope[h] = slope;
    out.slope_std[h] = std::sqrt(ss / std::max(1.0, count - groups - 1) / sdd);
    out.ranges[h] = static_cast<long>(count);
  }
  return out;
}

std::vector<std::pair<int, double>> RangeGraph::rangeResidualsLessBias() const {
  std::vector<std::pair<int, double>> out;
  out.reserve(ranges_.size());
  for (const auto& r : ranges_)
    out.emplace_back(anchors_[static_cast<size_t>(r.anchor)].id, rangeResidual(r, nullptr));
  return out;
}

std::vector<std::pair<int, double>> RangeGraph::rangeResiduals() const {
  auto out = rangeResidualsLessBias();
  for (size_t k = 0; k < ranges_.size(); ++k)
    out[k].second += biases_[biasIndex(ranges_[k].anchor)];
  return out;
}

std::vector<AnchorResiduals> RangeGraph::anchorResiduals() const {
  std::vector<std::vector<double>> raw(anchors_.size()), centred(anchors_.size());
  for (const auto& r : ranges_) {
    const double e = rangeResidual(r, nullptr);
    raw[static_cast<size_t>(r.anchor)].push_back(e + biases_[biasIndex(r.anchor)]);
    centred[static_cast<size_t>(r.anchor)].push_back(e);
  }
  std::vector<AnchorResiduals> out;
  for (size_t i = 0; i < anchors_.size(); ++i) {
    AnchorResiduals a;
    a.anchor_id = anchors_[i].id;
    a.ranges = static_cast<long>(raw[i].size());
    a.bias = biases_[biasIndex(static_cast<int>(i))];
    const auto half = raw[i].begin() + static_cast<std::ptrdiff_t>(raw[i].size() / 2);
    a.median = medianOf(raw[i]);
    a.median_first_half = medianOf({raw[i].begin(), half});
    a.median_second_half = medianOf({half, raw[i].end()});
    const double m = medianOf(centred[i]);
    for (auto& e : centred[i]) e = std::abs(e - m);
    a.robust_sigma = 1.4826 * medianOf(std::move(centred[i]));
    out.push_back(a);
  }
  return out;
}

std::map<int, std::pair<long, double>> RangeGraph::tagSigmas() const {
  std::map<int, std::vector<double>> residuals;
  for (const auto& r : ranges_) residuals[r.tag_id].push_back(rangeResidual(r, nullptr));
  std::map<int, std::pair<long, double>> out;
  for (auto& [tag, e] : residuals) {
    const double m = medianOf(e);
    for (auto& x : e) x = std::abs(x - m);
    out[tag] = {static_cast<long>(e.size()), 1.4826 * medianOf(e)};
  }
  return out;
}

}  // namespace uwbloc::loc::graph
