// The range error as a mixture: a Gaussian line-of-sight part and a non-line-of-sight part in
// which the range reads long by an exponential excess (an exponentially modified Gaussian),
//   p(e) = (1 - w) N(e; 0, s) + w EMG(e; s, m),
//   EMG(e; s, m) = (1 / m) exp(s^2 / (2 m^2) - e / m) Phi(e / s - s / m),
// e the range minus the predicted distance, w the NLOS fraction, s the noise std and m the mean
// NLOS excess. Where most ranges are NLOS (a robot among walls), a Gaussian of any width takes
// the excess for noise about a longer distance and pulls the estimate away from the anchors; the
// mixture explains it and the shortest ranges place the robot. It is learnt from the residuals
// of a solved path (fitRangeMixture) and kept only when it explains them better than one
// Gaussian by more than its extra parameters cost (BIC).
#pragma once

#include <map>
#include <optional>
#include <utility>
#include <vector>

namespace uwbloc::loc {

struct RangeMixture {
  double nlos_fraction = 0.0;  ///< w, in (0, 1)
  double sigma = 0.1;          ///< s [m]
  double nlos_mean = 0.5;      ///< m, the mean NLOS excess [m]
  /// The share of each range's log-density a filter counts: 1 / the residuals' integrated
  /// autocorrelation time in ranges (integratedAutocorrelationTime, the median over anchors).
  /// Ranges whose errors persist over many ranges (an anchor out of sight for a while, the pose's
  /// own slow error) carry less than one range's information each; a filter that multiplies their
  /// densities as if independent grows sure of where they pull it. 1 when not learnt.
  double weight = 1.0;

  /// log p(e) with the LOS std widened to `sigma_eff` (>= sigma: the state's own uncertainty,
  /// or an NLOS model's doubt): both parts take it.
  double logDensity(double e, double sigma_eff) const;
  double logDensity(double e) const { return logDensity(e, sigma); }
  /// P(NLOS | e): the NLOS part's share of the density at e, with `prior` in place of w (held
  /// within [0.01, 0.99]) and both parts at `sigma_eff`. 0 where the NLOS part has no density (e
  /// far below zero).
  double nlosPosterior(double e, double sigma_eff, double prior) const;
  /// This mixture with w set to `w` (held within [0.01, 0.99]: the LOS part keeps 1 %).
  RangeMixture withNlosFraction(double w) const;
  /// Whether neither part explains e: its density (at `sigma_eff`) falls below the LOS part's
  /// at k sigma_eff (a range too short, or longer than the NLOS excess explains).
  bool outside(double e, double sigma_eff, double k) const;
};

/// A range edge's residual under a RangeMixture, for a least-squares solver: with L(e) the
/// log-density (the mixture at std `sigma_eff`, plus a floor at the LOS part's density
/// `floor_k` stds out, so that a range neither part explains stops pulling) and e* its mode,
///   f(e) = sign(e - e*) sqrt(2 (L(e*) - L(e))),
/// so that f^2 / 2 is the negative log-likelihood up to a constant, and f is smooth and
/// increasing through the mode (f' = -L'(e) / f, and sqrt(-L''(e*)) at the mode). A range that
/// reads long by the NLOS excess costs little; one as short costs as much as a Gaussian's.
class MixtureResidual {
 public:
  MixtureResidual(const RangeMixture& mixture, double sigma_eff, double floor_k = 4.0);
  /// f(e), and f'(e) when `slope` is given.
  double operator()(double e, double* slope = nullptr) const;
  double mode() const { return mode_; }

 private:
  /// L(e) and, when given, L'(e).
  double logDensity(double e, double* slope) const;
  RangeMixture mixture_;
  double sigma_, log_floor_;
  double mode_ = 0.0, log_mode_ = 0.0, slope_at_mode_ = 1.0;
};

/// Each link's (anchor and tag) NLOS state, tracked as a two-state Markov chain over its ranges.
/// An anchor stays out of sight while the robot crosses a room, so the state persists from one
/// range to the next; the mixture's w is only its share over the whole run. The chance that a
/// link's next range is NLOS is the posterior of its last (RangeMixture::nlosPosterior) relaxed
/// toward w with time constant `memory`: p(t) = w + (p_last - w) exp(-(t - t_last) / memory).
/// A link not seen yet starts at w. The ranges of one link are then independent given its
/// state. With one w for every range, a link in sight all along is read as 80 % NLOS and pulled
/// toward its anchor: CARMEN intel with six simulated anchors, four of them in sight or out of it
/// all along, fused-pf 0.124 m against 0.084 m with the state tracked (lidar-mcl 0.105 m).
class NlosStateTrack {
 public:
  explicit NlosStateTrack(double memory) : memory_(memory) {}
  bool enabled() const { return memory_ > 0.0; }
  /// The chance that the link's range at time t is NLOS, before the range is seen (w when the
  /// track is off).
  double prior(int anchor, int tag, double t, double w) const;
  /// The link's posterior after its range at time t.
  void update(int anchor, int tag, double t, double posterior);
  void clear() { links_.clear(); }

 private:
  struct Link {
    double posterior = 0.0;
    double t = 0.0;
  };
  double memory_;
  std::map<std::pair<int, int>, Link> links_;
};

/// One range for nlosStatePriors: its link (anchor and tag), time, residual (before the
/// mixture: range minus predicted distance, less any bias) and the LOS std it takes [s, m, m].
struct NlosSample {
  int anchor = 0, tag = 0;
  double t = 0.0, residual = 0.0, sigma = 0.1;
};
/// Each range's NLOS prior from its own link's other ranges, a smoothing (in both directions) of
/// their NLOS posteriors under `m` (RangeMixture::nlosPosterior at w) in time: with
/// K = exp(-|t_j - t_i| / memory) over the link's other ranges j,
///   p_i = (w + sum_j K post_j) / (1 + sum_j K),
/// the mixture's w counting as one range. An anchor out of sight while the robot crosses a room
/// makes a run of long ranges, and its ranges' NLOS chance is that run's, not the run's share
/// over all ranges: a link in sight all along is then read as LOS and its short ranges place the
/// path. The memory is chosen from the data: each candidate (1/16 s to 256 s, doubling) is scored
/// by the leave-one-out log-likelihood of every residual under the mixture at its own prior (range
/// i left out of its prior), and the best kept only when it beats w for every range. Nothing
/// when no candidate does (NLOS that does not persist in time, or no NLOS), or `samples` (in any
/// order) has fewer than 100 ranges.
struct NlosStatePriors {
  double memory = 0.0;               ///< [s]
  double log_likelihood_gain = 0.0;  ///< per range, over w for every range
  std::vector<double> priors;        ///< in the order of `samples`
};
std::optional<NlosStatePriors> nlosStatePriors(const RangeMixture& m,
                                               const std::vector<NlosSample>& samples);

/// The mixture's fit to range residuals after a solve, each with its anchor id: maximum
/// likelihood (Ceres) over w, s, m and one offset (where the LOS residuals lie: the solved
/// path's own pull), from at most 20 000 residuals (a longer run's thinned evenly). Nothing when:
/// - there are fewer than 100 residuals, or the fit fails;
/// - the mixture's BIC (4 parameters) is not below one Gaussian's (mean and std) and below a
///   Gaussian's with a mean per anchor and one std: a bias shifts every range of one anchor,
///   and biases explain it better (one anchor of three 1 m long is not NLOS);
/// - w < 0.05, or m <= s (a skew of the noise, not a second mode).
struct RangeMixtureFit {
  RangeMixture mixture;
  double offset = 0.0;                          ///< where the LOS residuals lie [m]
  double log_likelihood = 0.0;                  ///< per residual
  double gaussian_log_likelihood = 0.0;         ///< one mean and std, per residual
  double biased_gaussian_log_likelihood = 0.0;  ///< a mean per anchor and one std
};
std::optional<RangeMixtureFit> fitRangeMixture(
    const std::vector<std::pair<int, double>>& residuals);

/// The integrated autocorrelation time of a series, in samples: tau = 1 + 2 sum_{k=1..M} rho_k,
/// rho_k the autocorrelation at lag k about the mean, and M the first lag with M >= 5 tau(M)
/// (Sokal's automatic window), at most a quarter of the series. 1 for white noise, about
/// (1 + a) / (1 - a) for an AR(1) series of coefficient a; never below 1. 1 when the series has
/// fewer than 20 samples or no variance.
double integratedAutocorrelationTime(const std::vector<double>& x);

/// RangeMixture::weight from residuals in the order their ranges came, each with its anchor id:
/// 1 / the median over the anchors of each one's integratedAutocorrelationTime.
double independentShare(const std::vector<std::pair<int, double>>& residuals);

}  // namespace uwbloc::loc
