// Particle-filter localisers on the common core: lidar-mcl (LiDAR likelihood field on the map),
// fused-naive (LiDAR and UWB likelihoods multiplied, as MRPT's pf-localization does with a beacon
// map plus a grid) and fused-pf (the same, with UWB NLOS rejection from the LiDAR pose).
//
// NLOS test (fused-pf): after the motion prediction and the LiDAR update, the filter's mean p̂
// and covariance P predict each tag-anchor distance d̂ = h(p̂) with Jacobian J; a range is
// flagged when |d - d̂| > k sqrt(sigma_uwb^2 + J P J^T). Flagged ranges are rejected or
// down-weighted (sigma multiplied). The geometric test (ray-cast of the tag-anchor segment on
// the grid from p̂) is evaluated alongside and can be chosen instead; both decisions are
// recorded for every range so the two detectors can be scored on the same data.
//
// Measurements are processed per epoch (everything with one timestamp: a scan and its ranges):
// weight by the scan, test and weight the ranges, then either resample (SIR) or, with
// swarm = ibas, move the particles with the improved beetle swarm (PF-IBAS, the paper's
// §2.1.3): the fitness is the epoch's log-likelihood (eq. 26 over the NLOS-cleaned ranges, plus
// the LiDAR field), no particle is discarded, and the weights are the fitness at the moved
// positions (eq. 28), by default times the weight each particle carried into the epoch
// (`ibas_weights`). When the swarm's spread collapses below `min_spread`, jitter of that size is
// injected so that the estimate cannot freeze.
#pragma once

#include <memory>
#include <string>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/lidar/landmarks.hpp"
#include "uwbloc/localization/lidar/likelihood_field.hpp"
#include "uwbloc/localization/optim/optimizers.hpp"
#include "uwbloc/localization/pf/particle_filter.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct PfLocalizerParams {
  int particles = 300;
  std::string resampler = "systematic";
  double ess = 0.5;  ///< resample when ESS / N < this
  MotionNoise motion;
  LikelihoodFieldParams field;
  std::string init = "tracking";       ///< tracking (box around the start pose) or global
  double init_xy = 0.5;                ///< tracking box half-width [m]
  double init_theta_deg = 20.0;        ///< tracking box half-width [deg]
  int init_n = 0;  ///< particles at the start, kept until the cloud converges (0: n)
  RangeFrontEndParams front;           ///< UWB range checks; sigma is the range likelihood's std
  std::string nlos = "lidar";          ///< NLOS test: lidar, raycast or none
  double nlos_k = 3.0;                 ///< gate width in standard deviations
  std::string nlos_action = "reject";  ///< reject or downweight
  double downweight = 5.0;             ///< sigma factor for down-weighted ranges
  /// The NLOS test judges ranges against the filter's pose; when most of an epoch's ranges (at
  /// least 2) fail it this many epochs in a row, the pose is more likely wrong than the ranges,
  /// and the test is suspended (the ranges are used) until they agree with the pose again.
  /// 0: never suspend.
  int nlos_suspend = 2;
  std::string swarm = "none";          ///< none (resampling) or ibas (PF-IBAS)
  int ibas_iterations = 5;             ///< IBAS iterations per epoch
  double ibas_step = 0.05;             ///< IBAS initial step [m, rad]
  bool ibas_theta = true;              ///< IBAS moves the heading too (else x, y only)
  double min_spread = 0.02;            ///< inject diversity below this swarm spread [m]
  bool ibas_resample = false;          ///< after the swarm, also resample when ESS/N < ess
  /// Weights after the swarm: "fitness" (eq. 28 as printed: the epoch's likelihood at the moved
  /// positions, whatever the particle weighed before), "sequential" (the weight it carried into
  /// the epoch times that likelihood: a proper sequential importance weight between
  /// resamplings) or "posterior" (sequential, times the predicted density's ratio between the
  /// moved and the original position, the predicted cloud taken as a Gaussian).
  std::string ibas_weights = "fitness";
  bool landmarks = true;               ///< build and save a corner-landmark map along the run
  double landmark_sigma = 0.05;        ///< std of a corner observation [m]

  template <class V>
  void visit(V&& v) {
    v("n", particles, "particles");
    v("resampler", resampler, "multinomial, systematic, stratified or residual");
    v("ess", ess, "resample when ESS/N falls below this");
    v("a1", motion.alpha1, "odometry noise: rotation per radian");
    v("a2", motion.alpha2, "odometry noise: rotation per metre [rad/m]");
    v("a3", motion.alpha3, "odometry noise: translation per metre");
    v("a4", motion.alpha4, "odometry noise: translation per radian [m/rad]");
    v("lf_sigma", field.sigma_hit, "likelihood field: endpoint std [m]");
    v("lf_zhit", field.z_hit, "likelihood field: weight of the Gaussian part");
    v("lf_zrand", field.z_rand, "likelihood field: weight of the uniform part");
    v("lf_decimation", field.decimation, "likelihood field: use every n-th ray");
    v("lf_max_dist", field.max_dist, "likelihood field: distances capped here [m]");
    v("lf_max_range", field.max_range, "likelihood field: ignore rays beyond [m]");
    v("init", init, "tracking or global");
    v("init_xy", init_xy, "tracking: half-width of the start box [m]");
    v("init_theta", init_theta_deg, "tracking: half-width of the start box [deg]");
    v("init_n", init_n,
      "particles at the start (0: n), down to n once the heading std < 10 deg and the planar "
      "std < 0.3 m (for an unknown start heading or global localisation)");
    front.visit(v);
    v("nlos", nlos, "NLOS test on UWB ranges: lidar, raycast or none");
    v("nlos_k", nlos_k, "NLOS gate width [std]");
    v("nlos_action", nlos_action, "reject or downweight flagged ranges");
    v("downweight", downweight, "sigma factor for down-weighted ranges");
    v("nlos_suspend", nlos_suspend,
      "suspend the NLOS test after this many epochs in a row in which most ranges (>= 2) fail "
      "it (0: never)");
    v("swarm", swarm, "none (resampling) or ibas (PF-IBAS: the swarm moves the particles)");
    v("ibas_iters", ibas_iterations, "IBAS iterations per epoch");
    v("ibas_step", ibas_step, "IBAS initial step [m, rad]");
    v("ibas_theta", ibas_theta, "IBAS moves the heading too");
    v("min_spread", min_spread, "inject diversity when the swarm spread falls below [m]");
    v("ibas_resample", ibas_resample, "after the swarm, also resample when ESS/N < ess");
    v("ibas_weights", ibas_weights,
      "weights after the swarm: fitness (eq. 28), sequential (carried weight x likelihood) or "
      "posterior (sequential x predicted-density ratio for the move)");
    v("landmarks", landmarks, "build a corner-landmark map (saved as <method>_landmarks.csv)");
    v("landmark_sigma", landmark_sigma, "std of a corner observation [m]");
  }
};

class PfLocalizer : public UwbEstimator {
 public:
  PfLocalizer(const PfLocalizerParams& params, const EstimatorContext& context, bool use_lidar,
              bool use_uwb);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::optional<PoseEstimate> doFinish() override;
  void reset() override;

 public:
  std::vector<std::pair<std::string, std::string>> artifacts() const override;
  const LandmarkMap& landmarkMap() const { return landmark_map_; }
  const ParticleFilter& filter() const { return pf_; }

 private:
  void initialise();
  std::optional<PoseEstimate> finishEpoch();
  /// The NLOS test of one range against the current estimate; weights the particles when used.
  void updateRange(const AcceptedRange& r, const ParticleEstimate& e);
  double epochLogLikelihood(double x, double y, double theta) const;
  void swarmMove();
  /// True while the NLOS test is suspended (see PfLocalizerParams::nlos_suspend).
  bool nlosSuspended() const;

  PfLocalizerParams params_;
  EstimatorContext context_;
  bool use_lidar_, use_uwb_;
  ParticleFilter pf_;
  std::unique_ptr<LikelihoodField> field_;
  LandmarkExtractionParams extraction_;
  LandmarkMap landmark_map_;
  // The open epoch.
  double epoch_t_ = 0.0;
  bool epoch_open_ = false, epoch_has_scan_ = false;
  LaserScan epoch_scan_;
  std::vector<AcceptedRange> epoch_ranges_, used_ranges_;
  // PF-IBAS state, kept to avoid allocating per epoch.
  optim::BeetleSwarm swarm_;
  Eigen::MatrixXd swarm_pos_, swarm_start_;  ///< swarm_start_: posterior weights only
  enum class SwarmWeights { kFitness, kSequential, kPosterior } weights_ = SwarmWeights::kFitness;
  ParticleEstimate predicted_;         ///< the cloud after the motion, before this epoch's data
  std::vector<double> prior_log_w_;    ///< the weights before this epoch's data
  optim::Box swarm_box_;     ///< reused every epoch
  std::string nlos_reason_;  ///< "nlos_<test>", built once
  int epoch_flagged_ = 0;    ///< ranges of the open epoch that failed the NLOS test
  int nlos_streak_ = 0;      ///< epochs in a row in which most ranges failed it
  std::string spread_log_;   ///< "t,spread_xy" rows (PF-IBAS)
};

}  // namespace uwbloc::loc
