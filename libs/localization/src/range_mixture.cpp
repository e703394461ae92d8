#include "uwbloc/localization/range_mixture.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc {

namespace {

constexpr double kMinResiduals = 100;
constexpr size_t kMaxResiduals = 20000;
constexpr double kMinNlosFraction = 0.05;
/// The LOS part keeps at least 1 %: the NLOS test measures a range against it.
constexpr double kMaxNlosFraction = 0.99;
/// nlosStatePriors: the time constants tried, doubling from the first to the last [s].
constexpr double kFirstNlosMemory = 1.0 / 16.0;
constexpr double kLastNlosMemory = 256.0;

/// The two parts' log-densities at e, unweighted: log N(e; 0, s) and log EMG(e; s, m), for
/// doubles and Jets. The EMG's log is taken as log(1/m) + s^2/(2 m^2) - e/m + log Phi(e/s - s/m);
/// far in Phi's lower tail (a range much shorter than the distance) erfc underflows, and the NLOS
/// part has no density there (has_nlos false).
template <class T>
struct PartLogDensities {
  T los, nlos;
  bool has_nlos = false;
};
template <class T>
PartLogDensities<T> partLogDensities(const T& e, const T& s, const T& m) {
  using std::erfc;
  using std::log;
  PartLogDensities<T> out;
  const T z = e / s;
  out.los = -T(0.5) * z * z - log(s) - T(0.5 * std::log(2.0 * M_PI));
  const T phi = T(0.5) * erfc(-(z - s / m) / T(M_SQRT2));
  out.has_nlos = phi > T(1e-300);
  out.nlos = out.has_nlos ? -log(m) + s * s / (T(2) * m * m) - e / m + log(phi) : out.los;
  return out;
}

/// log of (1 - w) N + w EMG from the parts' log-densities, for doubles and Jets; the LOS part
/// alone where the NLOS part has no density.
template <class T>
T mixtureLogDensity(const PartLogDensities<T>& parts, const T& w) {
  using std::exp;
  using std::log;
  const T log_los = log(T(1) - w) + parts.los;
  if (!parts.has_nlos) return log_los;
  const T log_nlos = log(w) + parts.nlos;
  const T hi = log_los > log_nlos ? log_los : log_nlos;
  const T lo = log_los > log_nlos ? log_nlos : log_los;
  return hi + log(T(1) + exp(lo - hi));
}

/// log of (1 - w) N(e; 0, s) + w EMG(e; s, m), for doubles and Jets.
template <class T>
T mixtureLogDensity(const T& e, const T& w, const T& s, const T& m) {
  return mixtureLogDensity(partLogDensities(e, s, m), w);
}

/// The LOS part's log-density (weight 1 - w) k stds out, std s: below it a range is one neither
/// part explains (RangeMixture::outside), and MixtureResidual's floor.
double losLogDensityAt(double w, double s, double k) {
  return std::log1p(-w) - 0.5 * k * k - std::log(s * std::sqrt(2.0 * M_PI));
}

/// One residual's negative log-likelihood under the mixture; the parameters are unconstrained:
/// offset, log s, logit w, log m.
struct MixtureCost {
  explicit MixtureCost(double e) : e_(e) {}
  template <class T>
  bool operator()(const T* offset, const T* log_s, const T* logit_w, const T* log_m,
                  T* residual) const {
    using std::exp;
    using std::sqrt;
    const T w = T(1) / (T(1) + exp(-logit_w[0]));
    const T nll = -mixtureLogDensity(T(e_) - offset[0], w, exp(log_s[0]), exp(log_m[0]));
    // Ceres minimises half the squared residuals: the residual is the root of 2 (nll + a
    // constant that keeps it positive).
    residual[0] = sqrt(T(2) * (nll + T(kShift)));
    return true;
  }
  static constexpr double kShift = 50.0;
  double e_;
};

struct Solved {
  RangeMixture mixture;
  double offset = 0.0;
  double ll = 0.0;  ///< summed
};

/// The maximum-likelihood fit from one start: the LOS part at quantile `q` of the (sorted)
/// residuals, s from the spread below it, a share `w` NLOS with the excess of the mean over it.
std::optional<Solved> solveFrom(const std::vector<double>& sorted, double q, double w) {
  const auto at = [&](double f) { return sorted[static_cast<size_t>(f * (sorted.size() - 1))]; };
  const double mean =
      std::accumulate(sorted.begin(), sorted.end(), 0.0) / static_cast<double>(sorted.size());
  double offset = at(q), log_s = std::log(std::max((at(q) - at(0.5 * q)) / 0.67, 1e-3)),
         logit_w = std::log(w / (1.0 - w)), log_m = std::log(std::max(mean - at(q), 0.05));
  ceres::Problem problem;
  for (double r : sorted)
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<MixtureCost, 1, 1, 1, 1, 1>(new MixtureCost(r)), nullptr,
        &offset, &log_s, &logit_w, &log_m);
  problem.SetParameterLowerBound(&log_s, 0, std::log(1e-3));
  problem.SetParameterUpperBound(&log_s, 0, std::log(100.0));
  problem.SetParameterLowerBound(&log_m, 0, std::log(1e-3));
  problem.SetParameterUpperBound(&log_m, 0, std::log(100.0));
  problem.SetParameterLowerBound(&logit_w, 0, -10.0);
  problem.SetParameterUpperBound(&logit_w, 0,
                                 std::log(kMaxNlosFraction / (1.0 - kMaxNlosFraction)));
  ceres::Solver::Options options;
  options.max_num_iterations = 100;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable()) return std::nullopt;
  Solved out;
  out.mixture.sigma = std::exp(log_s);
  out.mixture.nlos_fraction = 1.0 / (1.0 + std::exp(-logit_w));
  out.mixture.nlos_mean = std::exp(log_m);
  out.offset = offset;
  for (double r : sorted) out.ll += out.mixture.logDensity(r - offset);
  if (!std::isfinite(out.ll)) return std::nullopt;
  return out;
}

}  // namespace

double RangeMixture::logDensity(double e, double sigma_eff) const {
  return mixtureLogDensity(e, nlos_fraction, std::max(sigma_eff, 1e-6), nlos_mean);
}

MixtureResidual::MixtureResidual(const RangeMixture& mixture, double sigma_eff, double floor_k)
    : mixture_(mixture), sigma_(std::max(sigma_eff, 1e-6)) {
  log_floor_ = losLogDensityAt(mixture_.nlos_fraction, sigma_, floor_k);
  // The mode: the best of a grid over the LOS part and the NLOS excess, then golden-section
  // search within a grid step of it (the density is unimodal there).
  const double lo = -3.0 * sigma_, hi = 3.0 * sigma_ + 2.0 * mixture_.nlos_mean;
  constexpr int kGrid = 200;
  const double step = (hi - lo) / kGrid;
  double best = lo, best_l = logDensity(lo, nullptr);
  for (int i = 1; i <= kGrid; ++i)
    if (const double e = lo + i * step, l = logDensity(e, nullptr); l > best_l) {
      best = e;
      best_l = l;
    }
  const double ratio = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = best - step, b = best + step;
  for (int i = 0; i < 60; ++i) {
    const double c = b - ratio * (b - a), d = a + ratio * (b - a);
    if (logDensity(c, nullptr) > logDensity(d, nullptr))
      b = d;
    else
      a = c;
  }
  mode_ = 0.5 * (a + b);
  log_mode_ = std::max(logDensity(mode_, nullptr), best_l);
  // -L'' at the mode, by central differences of L'.
  const double h = 1e-3 * sigma_;
  double up = 0.0, down = 0.0;
  logDensity(mode_ + h, &up);
  logDensity(mode_ - h, &down);
  slope_at_mode_ = std::sqrt(std::max((down - up) / (2.0 * h), 1e-12));
}

double MixtureResidual::logDensity(double e, double* slope) const {
  using Jet = ceres::Jet<double, 1>;
  const Jet l = mixtureLogDensity(Jet(e, 0), Jet(mixture_.nlos_fraction), Jet(sigma_),
                                  Jet(mixture_.nlos_mean));
  // log(exp(l) + exp(floor)), and its slope: the floor's share of the density has none.
  const double hi = std::max(l.a, log_floor_);
  const double total = hi + std::log(std::exp(l.a - hi) + std::exp(log_floor_ - hi));
  if (slope) *slope = l.v[0] * std::exp(l.a - total);
  return total;
}

double MixtureResidual::operator()(double e, double* slope) const {
  double l_slope = 0.0;
  const double l = logDensity(e, slope ? &l_slope : nullptr);
  const double f = std::copysign(std::sqrt(2.0 * std::max(log_mode_ - l, 0.0)), e - mode_);
  if (slope) *slope = std::abs(f) > 1e-3 ? -l_slope / f : slope_at_mode_;
  return f;
}

double RangeMixture::nlosPosterior(double e, double sigma_eff, double prior) const {
  const auto parts = partLogDensities(e, std::max(sigma_eff, 1e-6), nlos_mean);
  if (!parts.has_nlos) return 0.0;
  prior = std::clamp(prior, 1.0 - kMaxNlosFraction, kMaxNlosFraction);
  // P = w N_nlos / (w N_nlos + (1 - w) N_los), as a logistic of the log-odds.
  const double log_odds = std::log(prior) - std::log1p(-prior) + parts.nlos - parts.los;
  return 1.0 / (1.0 + std::exp(-log_odds));
}

RangeMixture RangeMixture::withNlosFraction(double w) const {
  RangeMixture out = *this;
  out.nlos_fraction = std::clamp(w, 1.0 - kMaxNlosFraction, kMaxNlosFraction);
  return out;
}

double NlosStateTrack::prior(int anchor, int tag, double t, double w) const {
  const auto it = links_.find({anchor, tag});
  if (!enabled() || it == links_.end()) return w;
  const double dt = std::max(0.0, t - it->second.t);
  return w + (it->second.posterior - w) * std::exp(-dt / memory_);
}

void NlosStateTrack::update(int anchor, int tag, double t, double posterior) {
  links_[{anchor, tag}] = {posterior, t};
}

namespace {

/// nlosStatePriors' priors at one memory: per link, sums of the kernel weights and of the
/// weighted posteriors over the earlier ranges (forward) and the later ones (backward).
std::vector<double> smoothedPriors(const std::vector<std::vector<size_t>>& links,
                                   const std::vector<NlosSample>& samples,
                                   const std::vector<double>& post, double w, double memory) {
  std::vector<double> prior(samples.size(), w);
  for (const auto& idx : links) {
    const size_t n = idx.size();
    std::vector<double> num(n, w), den(n, 1.0);
    double a = 0.0, b = 0.0;  // forward sums: weight and weighted posteriors
    for (size_t i = 0; i < n; ++i) {
      if (i > 0) {
        const double k = std::exp(-(samples[idx[i]].t - samples[idx[i - 1]].t) / memory);
        a = k * (a + 1.0);
        b = k * (b + post[idx[i - 1]]);
      }
      den[i] += a;
      num[i] += b;
    }
    a = b = 0.0;
    for (size_t i = n; i-- > 0;) {
      if (i + 1 < n) {
        const double k = std::exp(-(samples[idx[i + 1]].t - samples[idx[i]].t) / memory);
        a = k * (a + 1.0);
        b = k * (b + post[idx[i + 1]]);
      }
      prior[idx[i]] = (num[i] + b) / (den[i] + a);
    }
  }
  return prior;
}

}  // namespace

std::optional<NlosStatePriors> nlosStatePriors(const RangeMixture& m,
                                               const std::vector<NlosSample>& samples) {
  if (samples.size() < kMinResiduals) return std::nullopt;
  std::map<std::pair<int, int>, std::vector<size_t>> by_link;
  for (size_t i = 0; i < samples.size(); ++i)
    by_link[{samples[i].anchor, samples[i].tag}].push_back(i);
  std::vector<std::vector<size_t>> links;
  for (auto& [link, idx] : by_link) {
    std::stable_sort(idx.begin(), idx.end(),
                     [&](size_t a, size_t b) { return samples[a].t < samples[b].t; });
    links.push_back(std::move(idx));
  }
  const double w = m.nlos_fraction;
  // Each range's two parts' densities, once: every candidate weighs them by its own priors.
  std::vector<PartLogDensities<double>> parts(samples.size());
  std::vector<double> post(samples.size());
  double base = 0.0;  // log-likelihood with w for every range
  for (size_t i = 0; i < samples.size(); ++i) {
    parts[i] = partLogDensities(samples[i].residual, std::max(samples[i].sigma, 1e-6), m.nlos_mean);
    post[i] = m.nlosPosterior(samples[i].residual, samples[i].sigma, w);
    base += mixtureLogDensity(parts[i], w);
  }
  std::optional<NlosStatePriors> best;
  double best_gain = 0.0;
  for (double memory = kFirstNlosMemory; memory <= kLastNlosMemory; memory *= 2.0) {
    auto prior = smoothedPriors(links, samples, post, w, memory);
    double ll = 0.0;
    for (size_t i = 0; i < samples.size(); ++i)
      ll += mixtureLogDensity(parts[i], m.withNlosFraction(prior[i]).nlos_fraction);
    const double gain = (ll - base) / static_cast<double>(samples.size());
    if (gain > best_gain) {
      best_gain = gain;
      best = NlosStatePriors{memory, gain, std::move(prior)};
    }
  }
  return best;
}

bool RangeMixture::outside(double e, double sigma_eff, double k) const {
  const double sd = std::max(sigma_eff, 1e-6);
  return logDensity(e, sd) < losLogDensityAt(nlos_fraction, sd, k);
}

std::optional<RangeMixtureFit> fitRangeMixture(
    const std::vector<std::pair<int, double>>& residuals) {
  // A long run's residuals are thinned evenly to kMaxResiduals (each costs a term of the fit).
  const size_t stride = residuals.size() / kMaxResiduals + 1;
  std::map<int, std::vector<double>> by_anchor;
  double n = 0.0;
  for (size_t i = 0; i < residuals.size(); i += stride)
    if (const auto& [anchor, e] = residuals[i]; std::isfinite(e)) {
      by_anchor[anchor].push_back(e);
      ++n;
    }
  if (n < kMinResiduals) return std::nullopt;
  // The Gaussians: one mean and std, and a mean per anchor with one std.
  double sum = 0.0, sum_sq = 0.0, ss_anchor = 0.0;
  for (const auto& [anchor, e] : by_anchor) {
    const double mean = std::accumulate(e.begin(), e.end(), 0.0) / static_cast<double>(e.size());
    for (double r : e) {
      sum += r;
      sum_sq += r * r;
      ss_anchor += (r - mean) * (r - mean);
    }
  }
  const double var = sum_sq / n - (sum / n) * (sum / n), var_anchor = ss_anchor / n;
  if (!(var > 0.0) || !(var_anchor > 0.0)) return std::nullopt;
  RangeMixtureFit fit;
  fit.gaussian_log_likelihood = -0.5 * std::log(2.0 * M_PI * var) - 0.5;
  fit.biased_gaussian_log_likelihood = -0.5 * std::log(2.0 * M_PI * var_anchor) - 0.5;
  std::vector<double> sorted;
  for (const auto& [anchor, e] : by_anchor) sorted.insert(sorted.end(), e.begin(), e.end());
  std::sort(sorted.begin(), sorted.end());
  // The likelihood has several optima (a few ranges far long, or most a little), so the fit
  // starts three times and keeps the best: the LOS part at the residuals' 10th, 25th and 50th
  // percentile, 90, 50 and 20 % of them NLOS.
  std::optional<Solved> best;
  for (const auto& [q, w] : {std::pair{0.10, 0.9}, std::pair{0.25, 0.5}, std::pair{0.50, 0.2}})
    if (auto solved = solveFrom(sorted, q, w); solved && (!best || solved->ll > best->ll))
      best = solved;
  if (!best) return std::nullopt;
  fit.mixture = best->mixture;
  fit.offset = best->offset;
  fit.log_likelihood = best->ll / n;
  // BIC (k ln n - 2 ln L): the mixture's 4 parameters against the Gaussian's mean and std, and
  // against a Gaussian with a mean per anchor and one std (biases explain the residuals no
  // better); its NLOS part must be more than a skew of the noise (m > s). Each model pays for
  // its parameters: with 6 anchors seen from few places, the means fit NLOS excesses that differ
  // by anchor a little better than the mixture does (CARMEN aces with simulated UWB, the first
  // 60 s at the LiDAR's pose: 1680 ranges, 66 % NLOS, per residual -0.4525 against -0.4563),
  // which 3 more parameters do not pay for; a bias on one anchor wins by far (0.5 m over a
  // range std of 0.1 m).
  const auto bic = [&](double k, double ll) { return k * std::log(n) - 2.0 * n * ll; };
  const double mixture_bic = bic(4.0, fit.log_likelihood);
  const auto anchors = static_cast<double>(by_anchor.size());
  const bool better = mixture_bic < bic(2.0, fit.gaussian_log_likelihood) &&
                      mixture_bic < bic(anchors + 1.0, fit.biased_gaussian_log_likelihood);
  if (!better || fit.mixture.nlos_fraction < kMinNlosFraction ||
      fit.mixture.nlos_mean <= fit.mixture.sigma)
    return std::nullopt;
  return fit;
}

double integratedAutocorrelationTime(const std::vector<double>& x) {
  const size_t n = x.size();
  if (n < 20) return 1.0;
  double mean = 0.0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(n);
  double c0 = 0.0;
  for (double v : x) c0 += (v - mean) * (v - mean);
  if (!(c0 > 0.0)) return 1.0;
  double tau = 1.0;
  for (size_t k = 1; k <= n / 4; ++k) {
    double ck = 0.0;
    for (size_t i = 0; i + k < n; ++i) ck += (x[i] - mean) * (x[i + k] - mean);
    tau += 2.0 * ck / c0;
    if (static_cast<double>(k) >= 5.0 * tau) break;
  }
  return std::max(1.0, tau);
}

double independentShare(const std::vector<std::pair<int, double>>& residuals) {
  std::map<int, std::vector<double>> by_anchor;
  for (const auto& [anchor, e] : residuals) by_anchor[anchor].push_back(e);
  std::vector<double> taus;
  for (const auto& [anchor, e] : by_anchor) taus.push_back(integratedAutocorrelationTime(e));
  return taus.empty() ? 1.0 : 1.0 / medianOf(std::move(taus));
}

}  // namespace uwbloc::loc
