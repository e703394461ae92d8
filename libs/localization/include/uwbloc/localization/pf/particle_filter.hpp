// Particle-filter core over (x, y, theta). Particles live in contiguous arrays (structure of
// arrays) sized once; predict, weight, resample and estimate allocate nothing per step.
// Resampling is a strategy (multinomial, systematic, stratified, residual). The localiser's
// posterior step (pf/parts.hpp) chooses between resampling and the beetle swarm that moves the
// particles instead (PF-IBAS); the swarm still resamples through this strategy on degeneracy.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "uwbloc/localization/params.hpp"

namespace uwbloc::loc {

using Rng = std::mt19937_64;

/// Particle states and log-weights, one contiguous array per component.
struct ParticleSet {
  std::vector<double> x, y, theta, log_w;
  size_t size() const { return x.size(); }
  void resize(size_t n) {
    x.resize(n);
    y.resize(n);
    theta.resize(n);
    log_w.assign(n, 0.0);
  }
};

/// Log-likelihood of the current measurement for particle i.
using LogLikelihood = std::function<double(double x, double y, double theta)>;

/// What a log-likelihood adds to a particle's log-weight: a non-finite one counts as tiny.
inline double boundedLogLikelihood(double l) { return std::isfinite(l) ? l : -1e3; }

/// Odometry motion model with MRPT-like noise (Thrun's sample_motion_model_odometry):
/// the increment is split into rot1, trans, rot2, each perturbed with std
///   rot: alpha1 |rot| + alpha2 trans,   trans: alpha3 trans + alpha4 (|rot1| + |rot2|)
/// plus small floors so that a standing robot's cloud does not collapse.
struct MotionNoise {
  double alpha1 = 0.05;      ///< rotation noise per radian of rotation
  double alpha2 = 0.01;      ///< rotation noise per metre of translation [rad/m]
  double alpha3 = 0.05;      ///< translation noise per metre
  double alpha4 = 0.01;      ///< translation noise per radian [m/rad]
  double min_xy = 0.005;     ///< translation noise floor per step [m]
  double min_theta = 0.002;  ///< rotation noise floor per step [rad]
};

/// Where the resampling step goes: copy particles (classic strategies) or move them.
class ResamplingStrategy {
 public:
  virtual ~ResamplingStrategy() = default;
  virtual const char* name() const = 0;
  /// Called when the filter decides to resample. `weights` are normalised. Classic strategies
  /// fill `indices` (its size is the number to draw, which may be smaller than the number of
  /// weights) and the filter copies; a strategy that moves particles itself returns false.
  virtual bool selectIndices(const std::vector<double>& weights, std::vector<int>& indices,
                             Rng& rng) = 0;
};

enum class ResamplerKind { kMultinomial, kSystematic, kStratified, kResidual };
constexpr std::array<EnumName<ResamplerKind>, 4> enumNames(ResamplerKind) {
  return {{{ResamplerKind::kMultinomial, "multinomial"},
           {ResamplerKind::kSystematic, "systematic"},
           {ResamplerKind::kStratified, "stratified"},
           {ResamplerKind::kResidual, "residual"}}};
}

std::unique_ptr<ResamplingStrategy> makeResampler(ResamplerKind kind);

struct ParticleFilterParams {
  int particles = 300;
  double ess_threshold = 0.5;  ///< resample when ESS / N falls below this
  MotionNoise motion;
  /// A wide start (an unknown heading, global localisation) needs more particles than tracking
  /// does: when larger than `particles`, the filter starts with this many and resamples down to
  /// `particles` once the cloud has converged (heading std below `converged_theta` and planar
  /// std below `converged_xy`).
  int initial_particles = 0;
  double converged_theta = 10.0 * M_PI / 180.0;  ///< [rad]
  double converged_xy = 0.3;                     ///< [m]
  /// KLD-sampling (Fox, "Adapting the sample size in particle filters through KLD-sampling",
  /// IJRR 2003): when larger than `particles`, each resampling draws as many particles, between
  /// `particles` and this, as bound the Kullback-Leibler distance between the drawn set and the
  /// weighted one by `kld_epsilon` with probability 1 - delta (`kld_z` is its standard normal
  /// quantile), over a histogram of `kld_bin_xy` x `kld_bin_xy` x `kld_bin_theta` cells.
  int max_particles = 0;
  double kld_epsilon = 0.05;
  double kld_z = 2.3263478740408408;           ///< delta = 0.01
  double kld_bin_xy = 0.5;                     ///< [m]
  double kld_bin_theta = 10.0 * M_PI / 180.0;  ///< [rad]
};

/// Fox's bound: the sample count that keeps the Kullback-Leibler distance between the
/// maximum-likelihood histogram of `bins` occupied cells and the true one below `epsilon` with
/// probability 1 - delta, `z` being the standard normal's 1 - delta quantile (the Wilson-Hilferty
/// form of the chi-square quantile with bins - 1 degrees of freedom, halved over epsilon).
/// 1 for a single cell; `bins` may be fractional (an expected count).
double kldSampleCount(double bins, double epsilon, double z);

struct ParticleEstimate {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  double ess = 0.0;  ///< effective sample size after the last weighting
};

class ParticleFilter {
 public:
  ParticleFilter(const ParticleFilterParams& params, std::unique_ptr<ResamplingStrategy> resampler,
                 uint64_t seed);

  /// Tracking: particles from N(pose, diag(sigma^2)).
  void initGaussian(const Eigen::Vector3d& pose, const Eigen::Vector3d& sigma);
  /// Tracking from a box: uniform in pose +- half_width.
  void initUniformBox(const Eigen::Vector3d& pose, const Eigen::Vector3d& half_width);
  /// Global: uniform over the given free cells (x, y), heading uniform.
  void initUniform(const std::vector<Eigen::Vector2d>& free_cells, double cell_size);
  /// How many particles the next init starts with (down to `particles` once converged).
  void setStartParticles(int n) { params_.initial_particles = n; }

  /// Moves every particle by the odometry increment with sampled noise.
  void predict(const Eigen::Vector3d& delta);
  /// Moves every particle by `delta` in its own frame, without noise.
  void shift(const Eigen::Vector3d& delta);
  /// Adds the measurement's log-likelihood to every particle's log-weight.
  void weight(const LogLikelihood& log_likelihood);
  /// Normalises the weights (no resampling); returns the effective sample size.
  double normalize();
  /// Normalises the weights; resamples when ESS / N < threshold. Returns true if it resampled.
  bool normalizeAndResample();
  /// Weighted mean (angle on the circle) and covariance.
  ParticleEstimate estimate() const;

  bool initialised() const { return initialised_; }
  const ParticleSet& particles() const { return set_; }
  ParticleSet& particles() { return set_; }
  const std::vector<double>& weights() const { return w_; }
  Rng& rng() { return rng_; }
  long resamples() const { return resamples_; }
  /// KLD-sampling: how many resamplings drew more than `particles`, and the most drawn.
  long resamplesAboveLeast() const { return resamples_above_least_; }
  size_t mostDrawn() const { return most_drawn_; }
  void setMotion(const MotionNoise& motion) { params_.motion = motion; }
  /// The log of the measurements' marginal likelihood, p(z_1..z_k | odometry), summed over the
  /// normalisations since the last reset: each adds the log of the weights' sum against what
  /// they summed to after the previous one (1 once normalised, n once resampled or drawn).
  double logEvidence() const { return log_evidence_; }
  void resetEvidence() { log_evidence_ = 0.0; }

 private:
  ParticleFilterParams params_;
  std::unique_ptr<ResamplingStrategy> resampler_;
  Rng rng_;
  /// Sizes every array for the start (the larger of `particles` and `initial_particles`).
  void prepareStart();
  /// True while the start's extra particles are still there and the cloud has converged.
  bool readyToShrink() const;
  /// How many particles a resampling draws once the start's extra ones are gone: `particles`,
  /// or with KLD-sampling the smallest count m from it up to `max_particles` at which Fox's
  /// bound over the histogram cells that m draws from the weights are expected to occupy,
  /// sum over cells of 1 - (1 - W_cell)^m, is met.
  size_t drawCount();
  /// The count the filter tracks with: `particles`, at least 1.
  size_t leastCount() const { return static_cast<size_t>(std::max(1, params_.particles)); }
  bool wide_start_ = false;  ///< the start's extra particles are still there
  /// KLD-sampling's histogram: each particle's cell and weight, sorted by cell (reused).
  std::vector<std::pair<std::array<long, 3>, double>> cells_;
  std::vector<double> cell_mass_;

  ParticleSet set_, scratch_;
  std::vector<double> w_;
  std::vector<int> indices_;
  double last_ess_ = 0.0;
  long resamples_ = 0;
  long resamples_above_least_ = 0;
  size_t most_drawn_ = 0;
  double log_evidence_ = 0.0;
  double log_sum_before_ = 0.0;  ///< log of the weights' sum after the last normalisation
  bool initialised_ = false;
};

}  // namespace uwbloc::loc
