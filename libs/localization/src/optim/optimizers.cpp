#include "uwbloc/localization/optim/optimizers.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace uwbloc::optim {

namespace {

Eigen::VectorXd uniformIn(const Box& box, Rng& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::VectorXd x(box.lo.size());
  for (Eigen::Index i = 0; i < x.size(); ++i) x(i) = box.lo(i) + u(rng) * (box.hi(i) - box.lo(i));
  return x;
}

double sign(double v) { return (v > 0) - (v < 0); }

// Unit vector towards `to`, or zero when `to` is (numerically) `from`: the guard for a beetle
// that is its own personal or swarm best.
template <class A, class B>
SmallVec towards(const A& from, const B& to) {
  SmallVec d = to - from;
  const double n = d.norm();
  if (n > 1e-300)
    d /= n;
  else
    d.setZero();
  return d;
}

// Clamps x into the box, in place.
void clampInto(SmallVec& x, const Box& box) { x = x.cwiseMax(box.lo).cwiseMin(box.hi); }

// BAS, Jiang & Li 2017; eq. (8)-(14) for a single beetle.
class Bas : public Optimizer {
 public:
  const char* name() const override { return "BAS"; }
  Result minimize(const Objective& f, const Box& box, const RunSettings& s, Rng& rng) override {
    std::normal_distribution<double> g(0.0, 1.0);
    Result r;
    Eigen::VectorXd x = uniformIn(box, rng);
    r.best = x;
    r.value = f(x);
    double d = 2.0, delta = s.initial_step;
    const auto k = x.size();
    for (int it = 0; it < s.iterations; ++it) {
      Eigen::VectorXd b(k);
      for (Eigen::Index i = 0; i < k; ++i) b(i) = g(rng);
      b /= std::max(b.norm(), 1e-300);                        // eq. (8)
      const Eigen::VectorXd xr = box.clamp(x + d * b / 2.0);  // eq. (9)-(10)
      const Eigen::VectorXd xl = box.clamp(x - d * b / 2.0);
      const double fr = f(xr), fl = f(xl);
      r.evaluations += 2;
      x = box.clamp(x - delta * b * sign(fr - fl));  // eq. (12), minimising
      const double fx = f(x);
      ++r.evaluations;
      if (fx < r.value) {
        r.value = fx;
        r.best = x;
      }
      d = 0.95 * d + 0.01;  // eq. (13)
      delta *= 0.95;        // eq. (14)
    }
    return r;
  }
};

class Ibas : public Optimizer {
 public:
  Ibas(IbasParams params, const char* name) : params_(std::move(params)), name_(name) {}
  const char* name() const override { return name_; }
  Result minimize(const Objective& f, const Box& box, const RunSettings& s, Rng& rng) override {
    const IbasParams& p = params_;
    BeetleSwarm swarm(p);
    Eigen::MatrixXd pos(s.population, box.lo.size());
    for (int i = 0; i < s.population; ++i) pos.row(i) = uniformIn(box, rng).transpose();
    Result r;
    double best = 0.0;
    const Objective neg = [&f](const Eigen::Ref<const Eigen::VectorXd>& x) { return -f(x); };
    r.best =
        swarm.maximize(pos, neg, box, s.iterations, s.initial_step, rng, &best, &r.evaluations);
    r.value = -best;
    return r;
  }

 private:
  IbasParams params_;
  const char* name_;
};

// PSO with the paper's settings (c1 = c2 = 2, omega = 1), velocities clamped to 20 % of the box.
class Pso : public Optimizer {
 public:
  const char* name() const override { return "PSO"; }
  Result minimize(const Objective& f, const Box& box, const RunSettings& s, Rng& rng) override {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const int n = s.population;
    const auto k = box.lo.size();
    const Eigen::VectorXd vmax = 0.2 * (box.hi - box.lo);
    std::vector<Eigen::VectorXd> x(n), v(n), pb(n);
    std::vector<double> pv(n);
    Result r;
    r.value = 1e300;
    for (int i = 0; i < n; ++i) {
      x[i] = uniformIn(box, rng);
      v[i] = Eigen::VectorXd::Zero(k);
      pb[i] = x[i];
      pv[i] = f(x[i]);
      ++r.evaluations;
      if (pv[i] < r.value) {
        r.value = pv[i];
        r.best = x[i];
      }
    }
    for (int it = 0; it < s.iterations; ++it)
      for (int i = 0; i < n; ++i) {
        for (Eigen::Index j = 0; j < k; ++j)
          v[i](j) = std::clamp(1.0 * v[i](j) + 2.0 * u(rng) * (pb[i](j) - x[i](j)) +
                                   2.0 * u(rng) * (r.best(j) - x[i](j)),
                               -vmax(j), vmax(j));
        x[i] = box.clamp(x[i] + v[i]);
        const double fx = f(x[i]);
        ++r.evaluations;
        if (fx < pv[i]) {
          pv[i] = fx;
          pb[i] = x[i];
        }
        if (fx < r.value) {
          r.value = fx;
          r.best = x[i];
        }
      }
    return r;
  }
};

// Real-coded GA: tournament selection, arithmetic crossover (0.8), uniform mutation per gene
// (0.05), elitism of one.
class Ga : public Optimizer {
 public:
  const char* name() const override { return "GA"; }
  Result minimize(const Objective& f, const Box& box, const RunSettings& s, Rng& rng) override {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const int n = s.population;
    const auto k = box.lo.size();
    std::vector<Eigen::VectorXd> pop(n), next(n);
    std::vector<double> fit(n);
    Result r;
    r.value = 1e300;
    for (int i = 0; i < n; ++i) {
      pop[i] = uniformIn(box, rng);
      fit[i] = f(pop[i]);
      ++r.evaluations;
    }
    std::uniform_int_distribution<int> pick(0, n - 1);
    auto tournament = [&] {
      const int a = pick(rng), b = pick(rng);
      return fit[a] < fit[b] ? a : b;
    };
    for (int it = 0; it < s.iterations; ++it) {
      const int elite = static_cast<int>(std::min_element(fit.begin(), fit.end()) - fit.begin());
      if (fit[elite] < r.value) {
        r.value = fit[elite];
        r.best = pop[elite];
      }
      next[0] = pop[elite];
      for (int i = 1; i < n; ++i) {
        Eigen::VectorXd child = pop[tournament()];
        if (u(rng) < 0.8) {
          const double a = u(rng);
          child = a * child + (1 - a) * pop[tournament()];
        }
        for (Eigen::Index j = 0; j < k; ++j)
          if (u(rng) < 0.05) child(j) = box.lo(j) + u(rng) * (box.hi(j) - box.lo(j));
        next[i] = child;
      }
      std::swap(pop, next);
      for (int i = 0; i < n; ++i) {
        fit[i] = f(pop[i]);
        ++r.evaluations;
      }
    }
    const int elite = static_cast<int>(std::min_element(fit.begin(), fit.end()) - fit.begin());
    if (fit[elite] < r.value) {
      r.value = fit[elite];
      r.best = pop[elite];
    }
    return r;
  }
};

// Bat algorithm (Yang 2010): frequency in [0, 1], loudness A in [1, 2] decaying by alpha = 0.85,
// pulse rate r rising with gamma = 0.9.
class Bat : public Optimizer {
 public:
  const char* name() const override { return "BA"; }
  Result minimize(const Objective& f, const Box& box, const RunSettings& s, Rng& rng) override {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::normal_distribution<double> g(0.0, 1.0);
    const int n = s.population;
    const auto k = box.lo.size();
    std::vector<Eigen::VectorXd> x(n), v(n);
    std::vector<double> fx(n), loud(n), r0(n), rate(n);
    Result r;
    r.value = 1e300;
    for (int i = 0; i < n; ++i) {
      x[i] = uniformIn(box, rng);
      v[i] = Eigen::VectorXd::Zero(k);
      fx[i] = f(x[i]);
      ++r.evaluations;
      loud[i] = 1.0 + u(rng);
      r0[i] = u(rng);
      rate[i] = 0.0;
      if (fx[i] < r.value) {
        r.value = fx[i];
        r.best = x[i];
      }
    }
    for (int it = 1; it <= s.iterations; ++it) {
      double mean_loud = 0.0;
      for (double a : loud) mean_loud += a / n;
      for (int i = 0; i < n; ++i) {
        const double freq = u(rng);
        v[i] += (x[i] - r.best) * freq;
        Eigen::VectorXd cand = box.clamp(x[i] + v[i]);
        if (u(rng) > rate[i]) {  // local walk around the best
          Eigen::VectorXd step(k);
          for (Eigen::Index j = 0; j < k; ++j) step(j) = g(rng) * 0.01 * (box.hi(j) - box.lo(j));
          cand = box.clamp(r.best + step * mean_loud);
        }
        const double fc = f(cand);
        ++r.evaluations;
        if (fc <= fx[i] && u(rng) < loud[i]) {
          x[i] = cand;
          fx[i] = fc;
          loud[i] *= 0.85;
          rate[i] = r0[i] * (1.0 - std::exp(-0.9 * it));
        }
        if (fc < r.value) {
          r.value = fc;
          r.best = cand;
        }
      }
    }
    return r;
  }
};

}  // namespace

double inertiaWeight(int k, int t_max, double omega_max, double omega_min) {
  return omega_max - (omega_max - omega_min) * static_cast<double>(k) / std::max(t_max, 1);
}

double stepDecay(int k, int t_max, double delta_e0, double delta_e1) {
  const double exponent = 1.0 / (1.0 + 5.0 * k / std::max(t_max, 1)) - 1.0;
  return std::pow(delta_e0 / delta_e1, exponent);
}

SmallVec cauchyMutationPaper(const Eigen::Ref<const Eigen::VectorXd>& best, double u) {
  return best * (1.0 + 0.03 * std::tan((0.35 * u - 0.2) * M_PI));
}

SmallVec cauchyMutationScaled(const Eigen::Ref<const Eigen::VectorXd>& best,
                              const Eigen::Ref<const Eigen::VectorXd>& spread, double u) {
  return best + 0.03 * std::tan((0.35 * u - 0.2) * M_PI) * spread;
}

void BeetleSwarm::start(const Eigen::MatrixXd& x, const Objective& f, Search& s) {
  const auto n = x.rows();
  velocity_.setZero(n, x.cols());  // keeps its storage when the size repeats
  personal_best_ = x;
  personal_value_.resize(n);
  current_value_.resize(n);
  Eigen::Index best_i = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    personal_value_(i) = f(x.row(i).transpose());
    current_value_(i) = personal_value_(i);
    ++s.evaluations;
    if (personal_value_(i) > personal_value_(best_i)) best_i = i;
  }
  s.swarm_best = personal_best_.row(best_i).transpose();
  s.swarm_value = personal_value_(best_i);
  // Each beetle's own multiplier on the scheduled step (1 when adaptation is off).
  step_scale_.setOnes(n);
}

SmallVec BeetleSwarm::velocity(const Eigen::MatrixXd& x, Eigen::Index i, const Search& s,
                               const Eigen::VectorXd& vmax, Rng& rng) const {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto k = x.cols();
  const SmallVec xi = x.row(i).transpose();
  SmallVec v(k);
  // Eq. (21): inertia plus pulls towards the personal and the swarm best.
  if (params_.normalize_pulls)
    v = s.omega * velocity_.row(i).transpose() +
        params_.c1 * u(rng) * towards(xi, personal_best_.row(i).transpose()) +
        params_.c2 * u(rng) * towards(xi, s.swarm_best);
  else
    v = s.omega * velocity_.row(i).transpose() +
        params_.c1 * u(rng) * (personal_best_.row(i).transpose() - xi) +
        params_.c2 * u(rng) * (s.swarm_best - xi);
  v = v.cwiseMax(-vmax).cwiseMin(vmax);
  if (params_.move_mask.size() == k) v = v.cwiseProduct(params_.move_mask);
  // A beetle that is both its own and the swarm's best gets no pull, and its inertia dies
  // away: it would stop searching. It then explores like a BAS beetle, along a random unit
  // direction (eq. 8).
  if (v.norm() < 1e-3) {
    std::normal_distribution<double> g(0.0, 1.0);
    for (Eigen::Index j = 0; j < k; ++j) v(j) = g(rng);
    if (params_.move_mask.size() == k) v = v.cwiseProduct(params_.move_mask);
    v /= std::max(v.norm(), 1e-300);
  }
  return v;
}

void BeetleSwarm::moveBeetle(Eigen::MatrixXd& x, Eigen::Index i, const Objective& f, const Box& box,
                             const SmallVec& v, Search& s, Rng& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const SmallVec xi = x.row(i).transpose();
  // Eq. (22)-(24): antennae along V, then a step along V towards the better antenna. The antenna
  // length follows the step (BAS's eq. 11, delta = c d with c = 1) once the step has shrunk
  // below the eq. (13) length, so that the two antennae sample at the scale the beetle moves at.
  const double beetle_step = s.step * step_scale_(i);
  const double antenna = std::min(s.antenna, beetle_step);
  SmallVec probe = xi + v * antenna / 2.0;
  clampInto(probe, box);
  const double fr = f(probe);
  probe = xi - v * antenna / 2.0;
  clampInto(probe, box);
  const double fl = f(probe);
  // Equal antennae (a plateau) give eq. (24) no direction; the beetle then tries one of the two
  // at random instead of standing still, if so configured.
  double direction = sign(fr - fl);
  if (direction == 0.0 && params_.random_tie_direction) direction = u(rng) < 0.5 ? -1.0 : 1.0;
  SmallVec moved = xi + beetle_step * v * direction;
  clampInto(moved, box);
  double fm = f(moved);
  s.evaluations += 3;
  velocity_.row(i) = v.transpose();
  const bool worse = fm < current_value_(i);
  if (params_.adaptive_step)
    step_scale_(i) = worse ? step_scale_(i) * params_.step_shrink
                           : std::min(1.0, step_scale_(i) * params_.step_grow);
  if (params_.greedy && worse) {
    fm = current_value_(i);  // stay
  } else {
    x.row(i) = moved.transpose();
    current_value_(i) = fm;
  }
  if (fm > personal_value_(i)) {
    personal_value_(i) = fm;
    personal_best_.row(i) = x.row(i);
  }
  if (fm > s.iteration_value) {
    s.iteration_value = fm;
    s.iteration_best = i;
  }
  if (fm > s.swarm_value) {
    s.swarm_value = fm;
    s.swarm_best = x.row(i).transpose();
  }
}

void BeetleSwarm::mutateIterationBest(Eigen::MatrixXd& x, const Objective& f, const Box& box,
                                      Search& s, Rng& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto n = x.rows(), k = x.cols();
  const Eigen::Index b = s.iteration_best;
  // Eq. (25): Cauchy mutation of this iteration's best beetle, kept only if it improves.
  const SmallVec best = x.row(b).transpose();
  SmallVec moved;
  if (params_.frame_invariant_mutation) {
    SmallVec spread = x.colwise().mean().transpose();  // the swarm's mean, then its spread
    for (Eigen::Index c = 0; c < k; ++c)
      spread(c) =
          std::sqrt((x.col(c).array() - spread(c)).square().sum() / std::max<double>(n - 1, 1));
    if (params_.move_mask.size() == k) spread = spread.cwiseProduct(params_.move_mask);
    moved = cauchyMutationScaled(best, spread, u(rng));
  } else {
    moved = cauchyMutationPaper(best, u(rng));
  }
  clampInto(moved, box);
  const double fmu = f(moved);
  ++s.evaluations;
  if (fmu <= s.iteration_value) return;
  x.row(b) = moved.transpose();
  current_value_(b) = fmu;
  if (fmu > personal_value_(b)) {
    personal_value_(b) = fmu;
    personal_best_.row(b) = moved.transpose();
  }
  if (fmu > s.swarm_value) {
    s.swarm_value = fmu;
    s.swarm_best = moved;
  }
}

Eigen::VectorXd BeetleSwarm::maximize(Eigen::MatrixXd& x, const Objective& f, const Box& box,
                                      int iterations, double initial_step, Rng& rng,
                                      double* best_fitness, long* evaluations) {
  if (x.cols() > 32) throw std::invalid_argument("BeetleSwarm: at most 32 dimensions");
  const Eigen::VectorXd vmax = params_.max_speed * (box.hi - box.lo);
  Search s;
  start(x, f, s);
  s.step = initial_step;
  s.antenna = params_.antenna;
  for (int it = 0; it < iterations; ++it) {
    s.omega = inertiaWeight(it, iterations, params_.omega_max, params_.omega_min);  // eq. (18)
    s.iteration_best = 0;
    s.iteration_value = -1e300;
    for (Eigen::Index i = 0; i < x.rows(); ++i)
      moveBeetle(x, i, f, box, velocity(x, i, s, vmax, rng), s, rng);
    mutateIterationBest(x, f, box, s, rng);
    if (params_.schedule == StepSchedule::kPaper)
      s.step *= stepDecay(it + 1, iterations, params_.delta_e0, params_.delta_e1);  // eq. (19)-(20)
    else
      s.step *= std::pow(params_.final_step_ratio, 1.0 / std::max(iterations, 1));
    s.antenna = params_.antenna_decay * s.antenna + 0.01;  // eq. (13)
  }
  if (best_fitness) *best_fitness = s.swarm_value;
  if (evaluations) *evaluations += s.evaluations;
  return Eigen::VectorXd(s.swarm_best);
}

std::unique_ptr<Optimizer> makeOptimizer(const std::string& name) {
  if (name == "bas") return std::make_unique<Bas>();
  IbasParams p;
  if (name == "ibas") return std::make_unique<Ibas>(p, "IBAS");
  if (name == "ibas-scaled") {
    p.frame_invariant_mutation = true;
    return std::make_unique<Ibas>(p, "IBAS-scaled");
  }
  if (name == "ibas-fixed") {  // the geometric schedule alone, without per-beetle adaptation
    p.adaptive_step = false;
    p.final_step_ratio = 1e-3;
    return std::make_unique<Ibas>(p, "IBAS-fixed");
  }
  if (name == "ibas-distance-pulls") {  // eq. (21) without the normalisation, as in PSO
    p.normalize_pulls = false;
    return std::make_unique<Ibas>(p, "IBAS-dist");
  }
  if (name == "ibas-paper") {
    p.schedule = StepSchedule::kPaper;
    p.adaptive_step = false;
    return std::make_unique<Ibas>(p, "IBAS-paper");
  }
  if (name == "pso") return std::make_unique<Pso>();
  if (name == "ga") return std::make_unique<Ga>();
  if (name == "ba") return std::make_unique<Bat>();
  throw std::invalid_argument("unknown optimiser '" + name +
                              "' (known: bas, ibas, ibas-fixed, ibas-distance-pulls, ibas-paper, "
                              "ibas-scaled, pso, ga, ba)");
}

}  // namespace uwbloc::optim
