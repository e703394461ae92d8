// The one table of parameter limits. A limit keeps a value where the methods are defined and
// where their work stays bounded: particle counts and iterations that fit in memory and time,
// noise that is positive, gates that exist.
#include <cmath>
#include <cstdio>

#include "uwbloc/localization/params.hpp"

namespace uwbloc::loc {

const std::vector<ParamLimit>& paramLimits() {
  static const std::vector<ParamLimit> limits = {
      {"n", 1, 1e6, false, "particles: memory and time grow with them"},
      {"n_max", 0, 1e6, false, "particles at most (KLD-sampling)"},
      {"kld_epsilon", 0, 1, true, "a Kullback-Leibler distance bound"},
      {"kld_bin", 0, 1e3, true, "[m]"},
      {"kld_bin_theta", 0, 360, true, "[deg]"},
      {"init_n", 0, 1e6, false, "particles at the start"},
      {"relocalise_n", 0, 1e6, false, "particles when relocalising"},
      {"lost_fit", 0, 1, false, "a fraction of the usual scan fit"},
      {"lost_scans", 0, 1e6, false, "scans in a row"},
      {"respread", 0, 1, false, "a share of the particles"},
      {"respread_xy", 0, 1e3, false, "[m]"},
      {"respread_theta", 0, 180, false, "[deg]"},
      {"range_share", 0, 1, true, "a share of each range's log-likelihood"},
      {"nlos_memory", 0, 1e6, false, "[s]"},
      {"calib", 0, 1e6, false, "[s] of recording learnt from"},
      {"start_sigma", 0, 1e3, true, "[m]"},
      {"start_sigma_yaw", 0, 180, true, "[deg]"},
      {"noise_rounds", 0, 100, false, "variance re-estimates (each a re-solve)"},
      {"a1", 0, 10, false, "odometry noise"},
      {"a2", 0, 10, false, "odometry noise"},
      {"a3", 0, 10, false, "odometry noise"},
      {"a4", 0, 10, false, "odometry noise"},
      {"a_scale", 0, 100, true, "a factor on a1-a4"},
      {"ess", 0, 1, false, "a fraction of the particle count"},
      {"init_xy", 0, 1e3, false, "[m]"},
      {"init_theta", 0, 180, false, "[deg]"},
      {"lf_sigma", 0, 100, true, "[m]"},
      {"lf_zhit", 0, 1, false, "a weight"},
      {"lf_zrand", 0, 1, false, "a weight"},
      {"lf_decimation", 1, 1e5, false, "rays"},
      {"lf_max_dist", 0, 100, true, "[m]"},
      {"lf_max_range", 0, 1e4, true, "[m]"},
      {"landmark_sigma", 0, 100, true, "[m]"},
      {"sigma", 0, 100, true, "range noise [m]: zero would make every likelihood infinite"},
      {"max_range", 0, 1e5, true, "[m]"},
      {"iq_n", 1, 32, false, "the increment queue holds at most 32"},
      {"iq_zeta", 0, 1e3, false, ""},
      {"iq_vmax", 0, 1e3, false, "[m/s]"},
      {"iq_floor", 0, 1e3, false, "[m]"},
      {"nlos_reject", 0, 1, true, "a probability"},
      {"nlos_k", 0, 100, true, "[std]"},
      {"downweight", 1, 1e6, false, "a sigma factor"},
      {"nlos_suspend", 0, 1e6, false, "epochs"},
      {"ibas_iters", 1, 100, false, "swarm iterations per epoch"},
      {"ibas_step", 0, 1e3, true, "[m, rad]"},
      {"min_spread", 0, 1e3, false, "[m]"},
      {"q", 0, 1e6, true, "process noise density: negative would make P indefinite"},
      {"tau", 0, 1e6, false, "[s]"},
      {"sigma_a", 0, 1e3, true, "[m/s^2]"},
      {"sigma_yaw", 0, 1e3, true, "[rad/s^2]"},
      {"b", 0.5, 0.999, false, "forgetting factor: d_k = (1-b)/(1-b^(k+1)) needs b < 1"},
      {"gamma", 0, 1e6, false, "divergence bound (0: off)"},
      {"prior_steps", 0, 1e6, false, "steps (0: the first innovation replaces the start)"},
      {"r_floor", 0, 100, true, "[m]: keeps the estimated R positive definite"},
      {"bias_max", 0, 1e6, false, "[m]"},
      {"gate", 0, 1e6, true, "chi-square threshold"},
      {"huber", 0, 1e3, true, "[std]"},
      {"accel_psd", 0, 1e6, true, "[m^2/s^3]"},
      {"yaw_accel_psd", 0, 1e6, true, "[rad^2/s^3]"},
      {"restart_after", 0, 1e6, false, "[s]"},
      {"mobile_n", 2, 1000, false, "fixes: the stillness test's window"},
      {"mobile_var", 0, 1e4, true, "[m^2]"},
      {"max_gated", 1, 1e6, false, ""},
      {"readmit", 0, 1e6, false, ""},
      {"readmit_tol", 0, 1e3, false, "[m]"},
      {"init_residual", 0, 1e3, true, "[m]"},
      {"reinit_std", 0, 1e3, false, "[m] (0: never restart after an outage)"},
      {"window", 0, 1e4, false, "[s] (per-epoch methods) or vertices (graph)"},
      {"loss_scale", 0, 1e3, true, "[std]"},
      {"odom_xy", 0, 1e3, true, "[m]"},
      {"odom_xy_per_m", 0, 1e3, false, ""},
      {"odom_th", 0, 1e3, true, "[rad]"},
      {"odom_th_per_rad", 0, 1e3, false, ""},
      {"odom_noise", 0, 1e3, true, "a factor on the odometry edges' std"},
      {"anchor_prior", 0, 1e3, true, "[m]"},
      {"iterations", 1, 1e5, false, "solver iterations"},
      {"landmark_min_obs", 1, 1e6, false, ""},
      {"icp_xy", 0, 1e3, true, "[m]"},
      {"icp_th", 0, 1e3, true, "[rad]"},
      {"prior_min_xy", 0, 1e3, true, "[m]"},
      {"prior_min_theta", 0, 1e3, true, "[rad]"},
      {"decimation", 1, 1e5, false, "rays"},
      {"min_range", 0, 1e4, false, "[m]"},
      {"min_dist", 0, 1e3, true, "[m]: ICP's matching distance"},
      {"kf_dist", 0, 1e4, false, "[m]"},
      {"kf_angle", 0, 360, false, "[deg]"},
      {"iters", 1, 1e4, false, "ICP iterations"},
      {"alfa", 0, 1, true, "ICP's distance reduction factor"},
      {"dist", 0, 1e3, true, "[m]"},
      {"ang", 0, 10, true, "[deg]"},
      {"min_goodness", 0, 1, false, ""},
      {"search", 0, 180, false, "[deg] (0: off)"},
      {"line_dist", 0, 100, false, "[m] (0: point-to-point only)"},
      {"search_turn", 0, 360, false, "[deg]"},
      {"map_radius", 0, 1e4, false, "[m] (0: the last keyframe alone)"},
      {"map_path", 0, 1e5, false, "[m] (0: the last keyframe alone)"},
      {"heading_offset", -10, 10, false, "[rad]"},
      {"hinf", 0, 1e6, false, "the H-infinity bound over the smallest feasible (0: off)"},
      {"k0", 0, 100, true, "[std]"},
      {"k1", 0, 1e3, true, "[std]"},
      {"nlos_threshold", 0, 1e3, false, "[m]"},
      {"ut_alpha", 0, 10, true, "the points' spread"},
      {"ut_beta", 0, 10, false, ""},
      {"ut_kappa", -3.9, 100, false, "n + kappa > 0 with n = 4 (6 on two tags or more)"},
      {"groups", 1, 64, false, "local filters"},
      {"n0", 1, 1000, false, "ranges: the window's cost grows with it"},
      {"kn", 0, 1e3, false, "ranges per metre"},
      {"c0", 0, 100, false, "[std]"},
      {"c1", 0, 100, false, "[std]"},
      {"beta", 0, 1, false, "a mixing weight"},
      {"p_reject", 0, 1, false, "a probability"},
      {"accel_noise", 0, 1e3, true, "[m/s^2/sqrt(Hz)]"},
      {"gyro_noise", 0, 1e3, true, "[rad/s/sqrt(Hz)]"},
      {"accel_bias_walk", 0, 1e3, false, ""},
      {"gyro_bias_walk", 0, 1e3, false, ""},
      {"still_window", 0, 60, true, "[s]: the detector keeps the window's samples"},
      {"still_acc", 0, 1e3, false, "[m/s^2]"},
      {"still_gyro", 0, 1e3, false, "[rad/s]"},
      {"still_rate", 0, 1e3, false, "[rad/s]"},
      {"fading_max", 1, 1e6, false, "a covariance factor (1: no fading)"},
  };
  return limits;
}

void checkLimit(const std::string& context, const std::string& key, double value) {
  char buf[160];
  if (!std::isfinite(value))
    throw ParamError(context + ": parameter '" + key + "' must be a finite number");
  for (const auto& l : paramLimits()) {
    if (key != l.key) continue;
    const bool below = l.min_exclusive ? !(value > l.min) : !(value >= l.min);
    if (below || !(value <= l.max)) {
      std::snprintf(buf, sizeof buf, "= %.6g must be in %s%g, %g]", value,
                    l.min_exclusive ? "(" : "[", l.min, l.max);
      throw ParamError(context + ": parameter '" + key + "' " + buf +
                       (l.why[0] ? std::string(" (") + l.why + ")" : ""));
    }
  }
}

}  // namespace uwbloc::loc
