#include "uwbloc/localization/pf/particle_filter.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "uwbloc/localization/events.hpp"

namespace uwbloc::loc {

namespace {

// The one walk every resampler shares: out[i] = the first j whose cumulative weight reaches
// target(i), for count ascending targets in (0, 1]. `weight(j)` is the normalised weight of j.
template <class Weight, class Target>
void walkCdf(size_t n, Weight weight, size_t count, Target target, int* out) {
  double cdf = weight(0);
  size_t j = 0;
  for (size_t i = 0; i < count; ++i) {
    const double t = target(i);
    while (t > cdf && j + 1 < n) cdf += weight(++j);
    out[i] = static_cast<int>(j);
  }
}

// m = idx.size() independent draws from the n weights. Sorted uniforms come from normalised
// cumulative sums of m + 1 exponential spacings, so one pass over the CDF suffices and nothing
// is allocated: a first pass sums the spacings, a second (same random stream, replayed) places
// the pointers.
class Multinomial : public ResamplingStrategy {
 public:
  const char* name() const override { return "multinomial"; }
  bool selectIndices(const std::vector<double>& w, std::vector<int>& idx, Rng& rng) override {
    const size_t n = w.size(), m = idx.size();
    std::exponential_distribution<double> e(1.0);
    const Rng start = rng;
    double total = 0.0;
    for (size_t i = 0; i <= m; ++i) total += e(rng);
    Rng replay = start;
    e.reset();
    double s = 0.0;
    walkCdf(
        n, [&](size_t j) { return w[j]; }, m, [&](size_t) { return (s += e(replay)) / total; },
        idx.data());
    return true;
  }
};

// One uniform offset, m evenly spaced pointers.
class Systematic : public ResamplingStrategy {
 public:
  const char* name() const override { return "systematic"; }
  bool selectIndices(const std::vector<double>& w, std::vector<int>& idx, Rng& rng) override {
    const size_t n = w.size(), m = idx.size();
    const double u0 = std::uniform_real_distribution<double>(0.0, 1.0 / m)(rng);
    walkCdf(
        n, [&](size_t j) { return w[j]; }, m,
        [&](size_t i) { return u0 + static_cast<double>(i) / m; }, idx.data());
    return true;
  }
};

// One uniform draw inside each of m equal strata.
class Stratified : public ResamplingStrategy {
 public:
  const char* name() const override { return "stratified"; }
  bool selectIndices(const std::vector<double>& w, std::vector<int>& idx, Rng& rng) override {
    const size_t n = w.size(), m = idx.size();
    std::uniform_real_distribution<double> u(0.0, 1.0);
    walkCdf(
        n, [&](size_t j) { return w[j]; }, m,
        [&](size_t i) { return (static_cast<double>(i) + u(rng)) / m; }, idx.data());
    return true;
  }
};

// floor(m w_i) copies of each particle, the remainder drawn systematically from the residuals.
class Residual : public ResamplingStrategy {
 public:
  const char* name() const override { return "residual"; }
  bool selectIndices(const std::vector<double>& w, std::vector<int>& idx, Rng& rng) override {
    const size_t n = w.size(), m = idx.size();
    size_t k = 0;
    double residual_total = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const auto copies = static_cast<size_t>(std::floor(m * w[i]));
      for (size_t c = 0; c < copies && k < m; ++c) idx[k++] = static_cast<int>(i);
      residual_total += m * w[i] - static_cast<double>(copies);
    }
    const size_t rest = m - k;
    if (rest == 0) return true;
    const double u0 = std::uniform_real_distribution<double>(0.0, 1.0 / rest)(rng);
    walkCdf(
        n, [&](size_t j) { return (m * w[j] - std::floor(m * w[j])) / residual_total; }, rest,
        [&](size_t i) { return u0 + static_cast<double>(i) / rest; }, idx.data() + k);
    return true;
  }
};

}  // namespace

std::unique_ptr<ResamplingStrategy> makeResampler(ResamplerKind kind) {
  switch (kind) {
    case ResamplerKind::kMultinomial:
      return std::make_unique<Multinomial>();
    case ResamplerKind::kSystematic:
      return std::make_unique<Systematic>();
    case ResamplerKind::kStratified:
      return std::make_unique<Stratified>();
    case ResamplerKind::kResidual:
      return std::make_unique<Residual>();
  }
  throw std::invalid_argument("unknown resampler");
}

ParticleFilter::ParticleFilter(const ParticleFilterParams& params,
                               std::unique_ptr<ResamplingStrategy> resampler, uint64_t seed)
    : params_(params), resampler_(std::move(resampler)), rng_(seed) {
  prepareStart();
}

double kldSampleCount(double bins, double epsilon, double z) {
  if (!(bins > 1.0)) return 1.0;
  const double a = 2.0 / (9.0 * (bins - 1.0));
  const double c = 1.0 - a + std::sqrt(a) * z;
  return (bins - 1.0) / (2.0 * epsilon) * c * c * c;
}

void ParticleFilter::prepareStart() {
  const auto n = static_cast<size_t>(std::max({1, params_.particles, params_.initial_particles}));
  wide_start_ = n > leastCount();
  // Every array is sized for the largest count it will hold, so that a resampling to a larger
  // count allocates nothing.
  const auto most = std::max(n, static_cast<size_t>(std::max(0, params_.max_particles)));
  for (auto* v : {&set_.x, &set_.y, &set_.theta, &set_.log_w, &scratch_.x, &scratch_.y,
                  &scratch_.theta, &scratch_.log_w, &w_})
    v->reserve(most);
  indices_.reserve(most);
  cells_.reserve(most);
  cell_mass_.reserve(most);
  set_.resize(n);
  scratch_.resize(n);
  w_.assign(n, 1.0 / n);
  indices_.assign(n, 0);
  log_sum_before_ = std::log(static_cast<double>(n));  // every start draws log-weights of 0
}

bool ParticleFilter::readyToShrink() const {
  if (!wide_start_) return false;
  const Eigen::Matrix3d c = estimate().covariance;
  return std::sqrt(std::max(c(2, 2), 0.0)) < params_.converged_theta &&
         std::sqrt(std::max(c(0, 0) + c(1, 1), 0.0)) < params_.converged_xy;
}

void ParticleFilter::initGaussian(const Eigen::Vector3d& pose, const Eigen::Vector3d& sigma) {
  prepareStart();
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 0; i < set_.size(); ++i) {
    set_.x[i] = pose.x() + sigma.x() * g(rng_);
    set_.y[i] = pose.y() + sigma.y() * g(rng_);
    set_.theta[i] = wrapAngle(pose.z() + sigma.z() * g(rng_));
    set_.log_w[i] = 0.0;
  }
  initialised_ = true;
}

void ParticleFilter::initUniformBox(const Eigen::Vector3d& pose, const Eigen::Vector3d& half) {
  prepareStart();
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (size_t i = 0; i < set_.size(); ++i) {
    set_.x[i] = pose.x() + half.x() * u(rng_);
    set_.y[i] = pose.y() + half.y() * u(rng_);
    set_.theta[i] = wrapAngle(pose.z() + half.z() * u(rng_));
    set_.log_w[i] = 0.0;
  }
  initialised_ = true;
}

void ParticleFilter::initUniform(const std::vector<Eigen::Vector2d>& free_cells, double cell) {
  if (free_cells.empty()) throw std::invalid_argument("global initialisation: no free cells");
  prepareStart();
  std::uniform_int_distribution<size_t> pick(0, free_cells.size() - 1);
  std::uniform_real_distribution<double> jitter(-0.5 * cell, 0.5 * cell), ang(-M_PI, M_PI);
  for (size_t i = 0; i < set_.size(); ++i) {
    const auto& c = free_cells[pick(rng_)];
    set_.x[i] = c.x() + jitter(rng_);
    set_.y[i] = c.y() + jitter(rng_);
    set_.theta[i] = ang(rng_);
    set_.log_w[i] = 0.0;
  }
  initialised_ = true;
}

void ParticleFilter::predict(const Eigen::Vector3d& delta) {
  // Decompose the increment into rotate - translate - rotate (Thrun et al., Table 5.6).
  const double trans = delta.head<2>().norm();
  const double rot1 = trans < 1e-6 ? 0.0 : std::atan2(delta.y(), delta.x());
  const double rot2 = wrapAngle(delta.z() - rot1);
  const auto& m = params_.motion;
  const double s_rot1 = m.alpha1 * std::abs(rot1) + m.alpha2 * trans + m.min_theta;
  const double s_rot2 = m.alpha1 * std::abs(rot2) + m.alpha2 * trans + m.min_theta;
  const double s_trans = m.alpha3 * trans + m.alpha4 * (std::abs(rot1) + std::abs(rot2)) + m.min_xy;
  std::normal_distribution<double> g(0.0, 1.0);
  for (size_t i = 0; i < set_.size(); ++i) {
    const double r1 = rot1 + s_rot1 * g(rng_);
    const double tr = trans + s_trans * g(rng_);
    const double r2 = rot2 + s_rot2 * g(rng_);
    const double heading = set_.theta[i] + r1;
    set_.x[i] += tr * std::cos(heading);
    set_.y[i] += tr * std::sin(heading);
    set_.theta[i] = wrapAngle(heading + r2);
  }
}

void ParticleFilter::shift(const Eigen::Vector3d& delta) {
  for (size_t i = 0; i < set_.size(); ++i) {
    const Pose2 p = composePose(Pose2(set_.x[i], set_.y[i], set_.theta[i]), delta);
    set_.x[i] = p.x(), set_.y[i] = p.y(), set_.theta[i] = p.z();
  }
}

void ParticleFilter::weight(const LogLikelihood& log_likelihood) {
  for (size_t i = 0; i < set_.size(); ++i) {
    const double l = log_likelihood(set_.x[i], set_.y[i], set_.theta[i]);
    set_.log_w[i] += boundedLogLikelihood(l);
  }
}

double ParticleFilter::normalize() {
  const size_t n = set_.size();
  // Normalise in log space: w_i = exp(l_i - max) / sum.
  const double max_l = *std::max_element(set_.log_w.begin(), set_.log_w.end());
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    w_[i] = std::exp(set_.log_w[i] - max_l);
    sum += w_[i];
  }
  if (sum > 0.0 && std::isfinite(sum) && std::isfinite(max_l))
    log_evidence_ += max_l + std::log(sum) - log_sum_before_;
  log_sum_before_ = 0.0;
  if (!(sum > 0.0) || !std::isfinite(sum)) {
    std::fill(w_.begin(), w_.end(), 1.0 / n);  // degenerate: fall back to uniform weights
  } else {
    for (auto& w : w_) w /= sum;
  }
  double sq = 0.0;
  for (double w : w_) sq += w * w;
  last_ess_ = 1.0 / sq;
  for (size_t i = 0; i < n; ++i) set_.log_w[i] = std::log(std::max(w_[i], 1e-300));
  return last_ess_;
}

bool ParticleFilter::normalizeAndResample() {
  normalize();
  // The start's extra particles go as soon as the cloud has converged; otherwise resample to
  // the same count when the weights have degenerated.
  const bool shrink = readyToShrink();
  size_t n = set_.size();
  if (!shrink && last_ess_ >= params_.ess_threshold * static_cast<double>(n)) return false;
  if (shrink) wide_start_ = false;
  if (!wide_start_) {
    n = drawCount();
    if (n > leastCount()) ++resamples_above_least_;
    most_drawn_ = std::max(most_drawn_, n);
  }
  indices_.resize(n);  // never grows past the reserved size: no allocation
  if (!resampler_->selectIndices(w_, indices_, rng_)) return true;
  scratch_.x.resize(n);
  scratch_.y.resize(n);
  scratch_.theta.resize(n);
  scratch_.log_w.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const auto j = static_cast<size_t>(indices_[i]);
    scratch_.x[i] = set_.x[j];
    scratch_.y[i] = set_.y[j];
    scratch_.theta[i] = set_.theta[j];
    scratch_.log_w[i] = 0.0;
  }
  std::swap(set_, scratch_);
  w_.resize(n);
  std::fill(w_.begin(), w_.end(), 1.0 / n);
  log_sum_before_ = std::log(static_cast<double>(n));
  ++resamples_;
  return true;
}

size_t ParticleFilter::drawCount() {
  const size_t least = leastCount();
  if (params_.max_particles <= params_.particles) return least;
  // The weighted set's histogram: the mass of each occupied cell.
  // A cell index for any value: the conversion of a value beyond long's range (or of a NaN) to
  // long is undefined, so those share the cells at the clamp.
  const auto cell = [](double v, double bin) {
    const double c = std::floor(v / bin);
    return static_cast<long>(std::isnan(c) ? 0.0 : std::clamp(c, -1e15, 1e15));
  };
  cells_.clear();
  for (size_t i = 0; i < set_.size(); ++i)
    cells_.push_back({{cell(set_.x[i], params_.kld_bin_xy), cell(set_.y[i], params_.kld_bin_xy),
                       cell(set_.theta[i], params_.kld_bin_theta)},
                      w_[i]});
  std::sort(cells_.begin(), cells_.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  cell_mass_.clear();
  for (size_t i = 0; i < cells_.size(); ++i) {
    if (i == 0 || cells_[i].first != cells_[i - 1].first) cell_mass_.push_back(0.0);
    cell_mass_.back() += cells_[i].second;
  }
  const auto occupied = [&](double m) {
    double k = 0.0;
    for (double mass : cell_mass_) k += 1.0 - std::pow(std::max(0.0, 1.0 - mass), m);
    return k;
  };
  // The bound grows with the cells m draws occupy, and they with m: from the least count, up
  // until the bound is met (each step raises m, so this ends).
  const auto most = static_cast<size_t>(params_.max_particles);
  size_t m = least;
  while (m < most) {
    const double need = std::ceil(
        kldSampleCount(occupied(static_cast<double>(m)), params_.kld_epsilon, params_.kld_z));
    if (!(need > static_cast<double>(m))) break;
    m = std::min(most, static_cast<size_t>(need));
  }
  return m;
}

ParticleEstimate ParticleFilter::estimate() const {
  ParticleEstimate e;
  double sx = 0, sy = 0, sc = 0, ss = 0;
  for (size_t i = 0; i < set_.size(); ++i) {
    sx += w_[i] * set_.x[i];
    sy += w_[i] * set_.y[i];
    sc += w_[i] * std::cos(set_.theta[i]);
    ss += w_[i] * std::sin(set_.theta[i]);
  }
  e.mean << sx, sy, std::atan2(ss, sc);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < set_.size(); ++i) {
    const Eigen::Vector3d d(set_.x[i] - sx, set_.y[i] - sy, wrapAngle(set_.theta[i] - e.mean.z()));
    cov += w_[i] * d * d.transpose();
  }
  e.covariance = cov;
  e.ess = last_ess_;
  return e;
}

}  // namespace uwbloc::loc
