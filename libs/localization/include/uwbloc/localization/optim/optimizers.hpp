// Swarm and evolutionary optimisers over a bounded box (all minimise; a maximisation problem
// passes -f). BAS and the improved beetle swarm IBAS follow the PF-IBAS paper, eq. (8)-(25);
// PSO, a real-coded GA and the bat algorithm are the paper's baselines with its settings.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace uwbloc::optim {

using Rng = std::mt19937_64;
/// Objectives see their argument through a Ref, so callers can pass stack vectors.
using Objective = std::function<double(const Eigen::Ref<const Eigen::VectorXd>&)>;
/// A point of at most 32 dimensions on the stack: the swarm's inner loop allocates nothing.
using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 32, 1>;

struct Box {
  Eigen::VectorXd lo, hi;
  Eigen::VectorXd clamp(const Eigen::VectorXd& x) const { return x.cwiseMax(lo).cwiseMin(hi); }
};

struct Result {
  Eigen::VectorXd best;
  double value = 0.0;
  long evaluations = 0;
};

struct RunSettings {
  int iterations = 200;
  int population = 30;
  double initial_step = 5.0;  ///< BAS/IBAS initial step delta_0
};

class Optimizer {
 public:
  virtual ~Optimizer() = default;
  virtual const char* name() const = 0;
  virtual Result minimize(const Objective& f, const Box& box, const RunSettings& s, Rng& rng) = 0;
};

/// Eq. (18): omega_K = omega_max - (omega_max - omega_min) K / T_max.
double inertiaWeight(int k, int t_max, double omega_max, double omega_min);

/// Eq. (19), read literally as printed:
///   delta_e(K) = (delta_e0 / delta_e1) ^ (1 / (1 + 5 K / T_max) - 1),
/// which is 1 at K = 0 and falls to (delta_e0/delta_e1)^(-5/6) (0.435 for 0.95 / 0.35) at
/// K = T_max: the step's decay factor per iteration. (The other common reading,
/// delta_e1 (delta_e0/delta_e1)^(1/(1+5K/T)), runs from delta_e0 to about 0.41; both shrink the
/// step faster as the search goes on. The paper's text claims the opposite.)
double stepDecay(int k, int t_max, double delta_e0 = 0.95, double delta_e1 = 0.35);

/// Eq. (25), the paper's Cauchy mutation: x_best (1 + 0.03 tan((0.35 u - 0.2) pi)), u ~ U(0,1).
/// It scales with |x| and so suits functions centred on the origin, not positions in a frame.
/// (The swarm runs this function and cauchyMutationScaled; the tests check the same ones.)
SmallVec cauchyMutationPaper(const Eigen::Ref<const Eigen::VectorXd>& best, double u);
/// Frame-invariant form: x_best + 0.03 s tan((0.35 u - 0.2) pi), s the swarm's spread per axis.
SmallVec cauchyMutationScaled(const Eigen::Ref<const Eigen::VectorXd>& best,
                              const Eigen::Ref<const Eigen::VectorXd>& spread, double u);

/// How the IBAS step shrinks: "paper" multiplies it by eq. (19)'s factor every iteration (eq. 20),
/// which shrinks it by 1e-5 within 40 of 200 iterations and freezes the swarm; "geometric"
/// shrinks it evenly from the initial step to `final_step_ratio` of it over the run.
enum class StepSchedule { kGeometric, kPaper };

struct IbasParams {
  double omega_max = 0.9, omega_min = 0.4;  ///< eq. (18)
  double c1 = 1.5, c2 = 1.5;                ///< eq. (21) weights of personal and swarm best
  /// Eq. (21) pulls along unit vectors (as printed); false pulls by the distance, as PSO does.
  bool normalize_pulls = true;
  double delta_e0 = 0.95, delta_e1 = 0.35;  ///< eq. (19)
  double antenna = 2.0;                     ///< initial antenna length d [units of the box]
  double antenna_decay = 0.95;              ///< eq. (13): d <- decay d + 0.01
  bool frame_invariant_mutation = false;    ///< eq. (25) as printed, or scaled by the spread
  double max_speed = 0.2;                   ///< velocity clamp, as a fraction of the box size
  StepSchedule schedule = StepSchedule::kGeometric;  ///< see StepSchedule
  /// A beetle keeps its place when its eq. (24) step would make it worse.
  bool greedy = true;
  /// Per-dimension mask on the velocity (empty: all 1). A 0 keeps that coordinate of every
  /// beetle fixed while the fitness still sees it (PF-IBAS moving x, y but not the heading).
  Eigen::VectorXd move_mask;
  /// Where the geometric schedule ends, as a fraction of the initial step.
  double final_step_ratio = 5e-3;
  /// Per-beetle step adaptation on top of the schedule: a beetle whose step made it worse
  /// multiplies its own step by `step_shrink`, one that did not by `step_grow` (never above
  /// the scheduled step). A beetle near an optimum then steps at the scale of its distance to
  /// it instead of overshooting until the schedule catches up.
  bool adaptive_step = true;
  /// Equal antennae (a plateau, e.g. the step function f3) leave eq. (24) without a direction:
  /// true steps one way at random, false keeps the beetle in place (a filter whose fitness is
  /// flat because an epoch carries no information must not move its particles).
  bool random_tie_direction = true;
  double step_grow = 1.2, step_shrink = 0.7;
};

/// The improved beetle swarm, usable on an external population (PF-IBAS moves particles with
/// it): `positions` (n x k, one beetle per row) is moved in place to maximise `fitness`.
class BeetleSwarm {
 public:
  explicit BeetleSwarm(IbasParams params = {}) : params_(params) {}
  /// Runs `iterations` IBAS iterations; returns the best position found (its fitness in
  /// `best_fitness`). Evaluations are counted in `evaluations`.
  Eigen::VectorXd maximize(Eigen::MatrixXd& positions, const Objective& fitness, const Box& box,
                           int iterations, double initial_step, Rng& rng, double* best_fitness,
                           long* evaluations);
  const IbasParams& params() const { return params_; }
  /// The initial antenna length d of the next maximize() runs (eq. 13 starts from it).
  void setAntenna(double d) { params_.antenna = d; }
  /// Fitness of each beetle at its position after the last maximize() (row order).
  const Eigen::VectorXd& values() const { return current_value_; }

 private:
  /// The state of one maximize() run besides the per-beetle arrays.
  struct Search {
    SmallVec swarm_best;
    double swarm_value = -1e300;
    Eigen::Index iteration_best = 0;
    double iteration_value = -1e300;
    double omega = 0.0, step = 0.0, antenna = 0.0;
    long evaluations = 0;
  };
  /// Evaluates the swarm where it stands: personal and swarm bests, unit step scales.
  void start(const Eigen::MatrixXd& x, const Objective& f, Search& s);
  /// Eq. (21): beetle i's velocity (a random unit direction when it has no pull).
  SmallVec velocity(const Eigen::MatrixXd& x, Eigen::Index i, const Search& s,
                    const Eigen::VectorXd& vmax, Rng& rng) const;
  /// Eq. (22)-(24): antennae along v and the step towards the better one.
  void moveBeetle(Eigen::MatrixXd& x, Eigen::Index i, const Objective& f, const Box& box,
                  const SmallVec& v, Search& s, Rng& rng);
  /// Eq. (25) on the iteration's best beetle, kept when it improves.
  void mutateIterationBest(Eigen::MatrixXd& x, const Objective& f, const Box& box, Search& s,
                           Rng& rng);

  IbasParams params_;
  Eigen::MatrixXd velocity_, personal_best_;
  Eigen::VectorXd personal_value_, current_value_, step_scale_;
};

/// "bas", "ibas" (geometric step schedule with per-beetle adaptation), "ibas-fixed" (the
/// schedule alone, ending at 1e-3), "ibas-distance-pulls" (eq. 21 unnormalised),
/// "ibas-paper" (eq. 19-20 as printed), "ibas-scaled" (frame-invariant mutation), "pso", "ga",
/// "ba".
std::unique_ptr<Optimizer> makeOptimizer(const std::string& name);

}  // namespace uwbloc::optim
