// The parts a particle-filter localiser is composed of (see ParticleLocalizer):
//  - the motion model: the odometry sampler of ParticleFilter (MotionNoise);
//  - measurement models, each owning one sensor's share of an epoch (everything with one
//    timestamp: a scan and its ranges): the LiDAR likelihood field, and UWB ranges with the NLOS
//    test;
//  - a posterior step: resampling by one of the strategies of particle_filter.hpp, or the
//    improved beetle swarm that moves the particles (PF-IBAS, the paper's §2.1.3).
// A registry entry chooses the parts; every option is an enum parsed once, when it is built.
#pragma once

#include <algorithm>
#include <array>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/lidar/landmarks.hpp"
#include "uwbloc/localization/lidar/likelihood_field.hpp"
#include "uwbloc/localization/optim/optimizers.hpp"
#include "uwbloc/localization/pf/particle_filter.hpp"
#include "uwbloc/localization/range_front_end.hpp"
#include "uwbloc/localization/range_noise.hpp"

namespace uwbloc::loc {

enum class InitMode { kTracking, kGlobal };
constexpr std::array<EnumName<InitMode>, 2> enumNames(InitMode) {
  return {{{InitMode::kTracking, "tracking"}, {InitMode::kGlobal, "global"}}};
}

/// The filter itself: particle count, resampling strategy, motion noise and start.
struct ParticleCoreParams {
  int particles = 300;  ///< n
  /// KLD-sampling's most particles (0, or at most n: a fixed count of n); see
  /// ParticleFilterParams::max_particles.
  int max_particles = 0;
  double kld_epsilon = 0.05;
  double kld_bin_xy = 0.5;          ///< [m]
  double kld_bin_theta_deg = 10.0;  ///< [deg]
  ResamplerKind resampler = ResamplerKind::kSystematic;
  double ess = 0.5;                     ///< resample when ESS / N < this
  MotionNoise motion;                   ///< odometry sampling noise
  /// a1-a4 are multiplied by this; auto: chosen at the learning start (see ParticleLocalizer).
  AutoDouble motion_scale{1.0};
  InitMode init = InitMode::kTracking;  ///< box around the start pose, or global
  double init_xy = 0.5;                 ///< tracking box half-width [m]
  double init_theta_deg = 20.0;         ///< tracking box half-width [deg]
  int init_n = 0;  ///< particles at the start, kept until the cloud converges (0: n)
  /// Between odometry increments, carry the particles to each measurement's time at the last
  /// increment's rate (see ParticleLocalizer::carryTo).
  bool carry = true;

  template <class V>
  void visit(V&& v) {
    v("n", particles, "particles (the fewest, with n_max)");
    v("n_max", max_particles,
      "KLD-sampling (Fox 2003): each resampling draws between n and this many particles, as many "
      "as bound the Kullback-Leibler distance between the drawn set and the weighted one by "
      "kld_epsilon with probability 0.99, over the cells the draw is expected to occupy; 0 (or "
      "at most n): always n");
    v("kld_epsilon", kld_epsilon, "KLD-sampling: the distance bound");
    v("kld_bin", kld_bin_xy, "KLD-sampling: the histogram's cell width [m]");
    v("kld_bin_theta", kld_bin_theta_deg, "KLD-sampling: the histogram's cell height [deg]");
    v("resampler", resampler, "multinomial, systematic, stratified or residual");
    v("ess", ess, "resample when ESS/N falls below this");
    v("a1", motion.alpha1, "odometry noise: rotation per radian");
    v("a2", motion.alpha2, "odometry noise: rotation per metre [rad/m]");
    v("a3", motion.alpha3, "odometry noise: translation per metre");
    v("a4", motion.alpha4, "odometry noise: translation per radian [m/rad]");
    v("a_scale", motion_scale,
      "a1-a4 are multiplied by this; auto: the scale among 2, 1, 1/2 ... 1/16 under which the "
      "ranges of the learning start are likeliest (the filter's marginal likelihood, run twice "
      "per scale over those seconds once the range model is learnt, from 1 down while it "
      "rises); 1 unless another beats it by more than ln 20 and 3 times the runs' own Monte "
      "Carlo spread; 1 without a learning start");
    v("init", init, "tracking or global");
    v("init_xy", init_xy, "tracking: half-width of the start box [m]");
    v("init_theta", init_theta_deg, "tracking: half-width of the start box [deg]");
    v("init_n", init_n,
      "particles at the start (0: n), down to n once the heading std < 10 deg and the planar "
      "std < 0.3 m (for an unknown start heading or global localisation)");
    v("carry", carry,
      "between odometry increments, carry the particles to each measurement's time at the last "
      "increment's rate, at most one increment's span ahead, without noise (the next increment "
      "undoes it and moves them with its own noise): ranges and scans faster than the odometry "
      "are weighed where the robot is when they are taken; 0: where it was at the last "
      "increment");
  }
};

/// The LiDAR measurement model: the map's likelihood field, and the corner-landmark map.
struct LidarPartParams {
  LikelihoodFieldParams field;
  bool landmarks = false;        ///< build and save a corner-landmark map along the run
  double landmark_sigma = 0.05;  ///< std of a corner observation [m]
  /// Lost (kidnapped, diverged): the scan's fit to the map at its best particle (the fraction of
  /// endpoints within lf_max_dist / 2 of an obstacle) stays below `lost_fit` times its usual
  /// level for `lost_scans` scans in a row (0: never). 10 scans: with 3, the CARMEN logs with
  /// simulated UWB relocalised where the filter was not lost (aces+uwb fused-pf: 5 restarts,
  /// 0.954 m against 0.297 m without); with 10 neither log restarts (seed 1: 0.297 and 0.494 m,
  /// as without), and the kidnapped robot is still found on the demo and in the room.
  double lost_fit = 0.5;
  int lost_scans = 10;
  int relocalise_n = 20000;  ///< particles spread over the map's free space when lost
  /// A scan that fits poorly (below lost_fit x its usual level at the best particle, before its
  /// own weighting) re-draws this share of the particles around the estimate, in a box as wide
  /// as the start's, before it weighs them (0: never; not when the cloud is already wider than
  /// the box). A cloud locked onto a wrong heading has no particle with the right one, and the
  /// scan alone cannot move it there: PF-IBAS's 40 particles held a heading 17-26 deg off for
  /// 25 s on CARMEN aces with simulated UWB (seed 4), the scan's fit near 0 against 0.9-1 before,
  /// and drifted 2.6 m along the odometry.
  double respread = 0.5;
  double respread_xy = 0.5;      ///< half-width of that box [m]
  double respread_theta = 20.0;  ///< half-width of that box [deg]
  /// Report the range model seen from the filter's pose (RangeModelProbe); weights nothing.
  bool range_model = false;

  template <class V>
  void visit(V&& v) {
    v("lf_sigma", field.sigma_hit, "likelihood field: endpoint std [m]");
    v("lf_zhit", field.z_hit, "likelihood field: weight of the Gaussian part");
    v("lf_zrand", field.z_rand, "likelihood field: weight of the uniform part");
    v("lf_decimation", field.decimation, "likelihood field: use every n-th ray");
    v("lf_max_dist", field.max_dist, "likelihood field: distances capped here [m]");
    v("lf_max_range", field.max_range, "likelihood field: ignore rays beyond [m]");
    v("landmarks", landmarks, "build a corner-landmark map (saved as <method>_landmarks.csv)");
    v("landmark_sigma", landmark_sigma, "std of a corner observation [m]");
    v("lost_fit", lost_fit,
      "lost when the scan's fit to the map (endpoints within lf_max_dist / 2) falls below this "
      "fraction of its usual level ...");
    v("lost_scans", lost_scans,
      "... for this many scans in a row, then relocalise over the map (0: never; try 3)");
    v("relocalise_n", relocalise_n, "particles spread over the map's free space when lost");
    v("respread", respread,
      "share of the particles re-drawn around the estimate when a scan fits below lost_fit x its "
      "usual level, before it weighs them (0: never)");
    v("respread_xy", respread_xy, "half-width of the box they are drawn in [m]");
    v("respread_theta", respread_theta, "half-width of the box they are drawn in [deg]");
    v("range_model", range_model,
      "judge the recording's ranges at the filter's pose, without using them: their std, and the "
      "LOS / NLOS mixture when it explains them better (the fused filters' learning start)");
  }
};

/// How a range is judged NLOS: not at all, against the filter's pose (|d - d̂| > k sqrt(S)),
/// or by ray-casting the tag-anchor segment on the map from the filter's pose.
enum class NlosTest { kNone, kPose, kRaycast };
constexpr std::array<EnumName<NlosTest>, 3> enumNames(NlosTest) {
  return {{{NlosTest::kNone, "none"}, {NlosTest::kPose, "pose"}, {NlosTest::kRaycast, "raycast"}}};
}
enum class NlosAction { kReject, kDownweight };
constexpr std::array<EnumName<NlosAction>, 2> enumNames(NlosAction) {
  return {{{NlosAction::kReject, "reject"}, {NlosAction::kDownweight, "downweight"}}};
}

/// The UWB measurement model: range checks, the range likelihood and the NLOS test.
struct UwbPartParams {
  RangeFrontEndParams front;        ///< range checks; sigma is the range likelihood's std
  BiasMode bias = BiasMode::kAuto;  ///< per-anchor range bias
  /// sigma=auto or a bias: the range model is learnt by smoothing this many seconds first [s]
  double calib = 60.0;
  NlosTest nlos = NlosTest::kPose;  ///< NLOS test
  double nlos_k = 3.0;              ///< gate width in standard deviations
  NlosAction nlos_action = NlosAction::kReject;
  double downweight = 5.0;  ///< sigma factor for down-weighted ranges
  /// The NLOS test judges ranges against the filter's pose; when most of an epoch's ranges (at
  /// least 2) fail it this many epochs in a row, the pose is more likely wrong than the ranges,
  /// and the test is suspended (the ranges are used) until they agree with the pose again.
  /// 0: never suspend.
  int nlos_suspend = 2;
  /// sigma=auto: the range likelihood becomes the LOS / NLOS mixture learnt at the start, when
  /// it explains the residuals better than one Gaussian (range_mixture.hpp).
  bool mixture = true;
  /// Several tags and a learning start: a tag whose ranges are clearly wider than all the tags'
  /// together gets its own std (learnTagScales).
  bool tag_sigma = true;
  /// In a filter with LiDAR and sigma=auto: the range mixture is learnt at the LiDAR's pose
  /// (lidar-mcl with range_model=1 over the first `calib_lidar` seconds), not from the
  /// smoothing's residuals, whose path the NLOS ranges bend; its LOS std is then taken as
  /// fitted. 0: from the smoothing.
  double calib_lidar = 120.0;
  /// In a filter with LiDAR, under the mixture learnt at the LiDAR's pose: lost when more than
  /// half of the last `lost_ranges` ranges fail the NLOS test (neither part of the mixture
  /// explains them); the filter then relocalises over the map. 0: never.
  int lost_ranges = 50;
  /// Under the mixture: the share of each range's log-density the filter counts; auto: the one
  /// learnt with the mixture (RangeMixture::weight, from the residuals at the LiDAR's pose or of
  /// the learning start's smoothing).
  AutoDouble range_share;
  /// Under the mixture: each link's NLOS state is tracked (NlosStateTrack), its memory this many
  /// seconds; 0: every range takes the mixture's NLOS fraction.
  double nlos_memory = 5.0;

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("bias", bias,
      "per-anchor range bias: 0, 1 or auto (when an anchor's median offset exceeds its spread)");
    v("calib", calib,
      "sigma=auto or bias: learn the range std and biases by smoothing (graph-uwb-odom) the "
      "first this many seconds, then filter them again with it [s]; 0: learn nothing");
    v("nlos", nlos, "NLOS test on UWB ranges: pose, raycast or none");
    v("nlos_k", nlos_k, "NLOS gate width [std]");
    v("nlos_action", nlos_action, "reject or downweight flagged ranges");
    v("downweight", downweight, "sigma factor for down-weighted ranges");
    v("nlos_suspend", nlos_suspend,
      "suspend the NLOS test after this many epochs in a row in which most ranges (>= 2) fail "
      "it (0: never)");
    v("mixture", mixture,
      "sigma=auto: take the LOS / NLOS range-error mixture (Gaussian + exponential excess) "
      "learnt at the start as the range likelihood, when it explains the residuals better than "
      "one Gaussian (BIC); the NLOS test then flags only ranges that neither part explains");
    v("tag_sigma", tag_sigma,
      "several tags, with a learning start: a tag whose ranges the learning finds wider than all "
      "the tags' together by more than 1.25 times takes the learnt std times that ratio (one "
      "std learnt over every tag is the tags' that range most); 0: one std for every tag");
    v("lost_ranges", lost_ranges,
      "with LiDAR, under the mixture learnt at its pose: lost (relocalise over the map) when "
      "more than half of the last this many ranges fail the NLOS test (0: never)");
    v("calib_lidar", calib_lidar,
      "with LiDAR and sigma=auto: learn the range mixture at the LiDAR's pose "
      "(lidar-mcl:range_model=1) over the first this many seconds, not from the smoothing's "
      "residuals, and take its LOS std as fitted [s]; 0: from the smoothing");
    v("range_share", range_share,
      "under the mixture, the share of each range's log-likelihood counted: auto = 1 / the "
      "integrated autocorrelation time (in ranges) of the residuals the mixture was learnt from "
      "(at the LiDAR's pose, or of the smoothing): ranges whose errors persist are not "
      "independent");
    v("nlos_memory", nlos_memory,
      "under the mixture, each anchor-tag link's NLOS state is tracked: the chance that its "
      "range is NLOS is the posterior of its last range relaxed toward the mixture's NLOS "
      "fraction with this time constant [s]; 0: every range takes the fraction");
  }
};

/// Weights after the swarm: "fitness" (eq. 28 as printed: the epoch's likelihood at the moved
/// positions, whatever the particle weighed before), "sequential" (the weight it carried into the
/// epoch times that likelihood: a proper sequential importance weight between resamplings) or
/// "posterior" (sequential, times the predicted density's ratio between the moved and the
/// original position, the predicted cloud taken as a Gaussian).
enum class SwarmWeights { kFitness, kSequential, kPosterior };
constexpr std::array<EnumName<SwarmWeights>, 3> enumNames(SwarmWeights) {
  return {{{SwarmWeights::kFitness, "fitness"},
           {SwarmWeights::kSequential, "sequential"},
           {SwarmWeights::kPosterior, "posterior"}}};
}

/// The epochs in which the swarm moves the particles: those that hold a scan (the others are
/// weighted and resampled, as in pf-sir), or every epoch.
enum class SwarmEpochs { kScans, kAll };
constexpr std::array<EnumName<SwarmEpochs>, 2> enumNames(SwarmEpochs) {
  return {{{SwarmEpochs::kScans, "scans"}, {SwarmEpochs::kAll, "all"}}};
}

/// The PF-IBAS posterior step (the paper's §2.1.3 with the changes the README measures).
struct SwarmPartParams {
  int iterations = 1;        ///< IBAS iterations per epoch (the paper: one)
  /// IBAS initial step [m, rad]; auto: the search box's planar width, which the paper's eq. (12)
  /// takes as the initial step ("its initial value consistent with the search region"). A beetle
  /// keeps its place when its step would make it worse, so a long first step costs nothing where
  /// the particle sits well, and finds the fit where the cloud is off.
  AutoDouble step;
  bool move_theta = false;   ///< the swarm moves the heading too (else x, y only)
  double min_spread = 0.02;  ///< inject diversity below this swarm spread [m]
  bool resample = true;      ///< after the swarm, also resample when ESS/N < ess
  SwarmWeights weights = SwarmWeights::kSequential;
  /// The paper's epochs hold a scan and its ranges. Where ranges come between the scans, one at
  /// a time, a swarm step per range drives the few particles onto one anchor's circle after
  /// another (CARMEN intel with simulated UWB, ranges at 54 Hz and scans 3.4 s apart: 0.275 m
  /// with every epoch, 0.142 m with the scans' only; the MRPT demo, whose ranges come with its
  /// scans, is the same either way).
  SwarmEpochs epochs = SwarmEpochs::kScans;

  template <class V>
  void visit(V&& v) {
    v("ibas_iters", iterations, "IBAS iterations per epoch");
    v("ibas_step", step,
      "IBAS initial step [m, rad]; auto: the width of the search box (the cloud's extent, at "
      "least 0.6 m), as the paper's eq. (12) starts from the search region");
    v("ibas_theta", move_theta, "IBAS moves the heading too");
    v("min_spread", min_spread, "inject diversity when the swarm spread falls below [m]");
    v("ibas_resample", resample, "after the swarm, also resample when ESS/N < ess");
    v("ibas_weights", weights,
      "weights after the swarm: fitness (eq. 28), sequential (carried weight x likelihood) or "
      "posterior (sequential x predicted-density ratio for the move)");
    v("ibas_epochs", epochs,
      "epochs in which the swarm moves the particles: scans (those holding a scan; the others "
      "are weighted and resampled) or all");
  }
};

/// How a measurement model learns over the first seconds of a recording.
struct Calibration {
  std::string learner;  ///< the method spec run on those events (its statistics are learnt)
  double span = 0.0;    ///< how long the batch lasts [s]
  /// When set, a second method run on the events of the first `mixture_span` seconds (at least
  /// `span`), whose range mixture (or its absence) replaces the learner's (the fused filters:
  /// lidar-mcl's range probe).
  std::string mixture_learner;
  double mixture_span = 0.0;
};

/// One sensor's share of an epoch.
class EpochMeasurement {
 public:
  virtual ~EpochMeasurement() = default;
  /// Takes `event` into the open epoch when it is this model's kind and usable; returns true
  /// then (the epoch opens or stays open).
  virtual bool take(const Event& event, EstimatorStatistics& stats) = 0;
  /// Multiplies the particles' weights by the epoch's likelihood (in log space).
  virtual void weight(ParticleFilter& pf, EstimatorStatistics& stats) = 0;
  /// Adds the epoch's log-likelihood at one pose to `l` (the swarm's fitness).
  virtual double addLogLikelihood(double l, double x, double y, double theta) const = 0;
  /// Closes the epoch once the filter has its estimate.
  virtual void endEpoch(const PoseEstimate& estimate) = 0;
  /// Forgets the state after a re-initialisation.
  virtual void reset() {}
  virtual void addArtifacts(std::vector<std::pair<std::string, std::string>>&) const {}
  /// A model that learns from a batch over the first seconds (a LearningStart): what learns
  /// it; nothing when it learns nothing.
  virtual std::optional<Calibration> calibration() const { return {}; }
  /// Takes what that method learnt (its statistics after its finishAll()).
  virtual void calibrate(const EstimatorStatistics&, EstimatorStatistics&) {}
  /// True when this model judges the filter lost (see LidarPartParams); asked after each epoch.
  virtual bool lost() const { return false; }
  /// The end of the stream, after the last epoch.
  virtual void finish(EstimatorStatistics&) {}
  /// Whether the open epoch holds a scan.
  virtual bool hasScan() const { return false; }
};

/// Log-likelihood of the epoch's data at one pose, summed over the measurement models.
using EpochFitness = std::function<double(double x, double y, double theta)>;

/// What replaces the plain Bayes weights with a new particle set at the end of an epoch.
class PosteriorStep {
 public:
  virtual ~PosteriorStep() = default;
  /// Called before the epoch's measurements weight the particles.
  virtual void beginEpoch(const ParticleFilter&) {}
  virtual void apply(ParticleFilter& pf, const EpochFitness& fitness, double t,
                     EstimatorStatistics& stats) = 0;
  /// Called before apply(): whether the epoch holds a scan.
  virtual void epochKind(bool /*scan*/) {}
  virtual void addArtifacts(std::vector<std::pair<std::string, std::string>>&) const {}
};

/// The LiDAR likelihood field on the map (needs a map); builds corner landmarks on request.
class LidarFieldMeasurement final : public EpochMeasurement {
 public:
  LidarFieldMeasurement(const LidarPartParams& params,
                        const std::shared_ptr<const OccupancyMap>& map);
  bool take(const Event& event, EstimatorStatistics& stats) override;
  void weight(ParticleFilter& pf, EstimatorStatistics& stats) override;
  double addLogLikelihood(double l, double x, double y, double theta) const override;
  void endEpoch(const PoseEstimate& estimate) override;
  void addArtifacts(std::vector<std::pair<std::string, std::string>>& out) const override;
  const LandmarkMap& landmarkMap() const { return landmark_map_; }
  bool hasScan() const override { return has_scan_; }
  bool lost() const override {
    return params_.lost_scans > 0 && low_fit_streak_ >= params_.lost_scans;
  }
  /// After a (re)start the cloud needs scans to converge: the test waits 10 x lost_scans.
  void reset() override {
    low_fit_streak_ = 0;
    hold_off_ = 10 * params_.lost_scans;
  }

 private:
  LidarPartParams params_;
  LikelihoodField field_;
  /// Re-draws a share of the particles when the scan fits them poorly (see `respread`).
  void respreadOnPoorFit(ParticleFilter& pf, EstimatorStatistics& stats);

  /// The scans' usual fit: a running mean (over the last 100 at most) of the fits judged not
  /// poor, the first 10 only building it.
  class FitLevel {
   public:
    /// Whether `fit` is below `ratio` x the usual level; a fit that is not joins the mean.
    bool poor(double fit, double ratio) {
      constexpr long kWarmUp = 10;
      if (n_ >= kWarmUp && fit < ratio * mean_) return true;
      ++n_;
      mean_ += (fit - mean_) / static_cast<double>(std::min(n_, 100L));
      return false;
    }

   private:
    double mean_ = 0.0;
    long n_ = 0;
  };
  FitLevel lost_level_;  ///< the lost test's, built after each start's hold-off
  /// The re-spread's, built from the first scan on (no hold-off after a start: a cloud that
  /// locks onto a wrong heading does so while it is still converging).
  FitLevel respread_level_;
  std::vector<double> scan_log_l_;  ///< each particle's scan log-likelihood this epoch
  int low_fit_streak_ = 0;          ///< poor scans in a row (lost_level_)
  int hold_off_ = 0;        ///< scans still to wait before judging the fit
  Eigen::Vector3d best_pose_ = Eigen::Vector3d::Zero();  ///< the epoch's best-fitting particle
  bool has_scan_ = false;
  LaserScan scan_;  ///< kept only for corner extraction
  LandmarkExtractionParams extraction_;
  LandmarkMap landmark_map_;
};

/// UWB ranges: the front end's checks, the NLOS test of each range against the filter's pose
/// after the epoch's other updates, and the Gaussian range likelihood (eq. 26, in logs).
class UwbRangeMeasurement final : public EpochMeasurement {
 public:
  /// The context's map is needed by the ray-cast test only, and used to record its decision
  /// when present.
  /// `with_lidar`: the filter also weighs scans (the range model may be learnt at their pose).
  UwbRangeMeasurement(const UwbPartParams& params, const EstimatorContext& context,
                      bool with_lidar = false);
  bool take(const Event& event, EstimatorStatistics& stats) override;
  void weight(ParticleFilter& pf, EstimatorStatistics& stats) override;
  double addLogLikelihood(double l, double x, double y, double theta) const override;
  void endEpoch(const PoseEstimate&) override { epoch_.clear(); }
  void reset() override {
    nlos_streak_ = 0;
    recent_failed_.clear();
    nlos_state_.clear();
  }
  bool lost() const override;
  std::optional<Calibration> calibration() const override;
  void calibrate(const EstimatorStatistics& learnt, EstimatorStatistics& stats) override;

 private:
  /// The NLOS test of one range against the estimate e; weights the particles when it is used.
  void weightRange(ParticleFilter& pf, const AcceptedRange& r, const ParticleEstimate& e,
                   EstimatorStatistics& stats);
  bool suspended() const;
  /// Several tags: the learnt std of each tag's ranges (estimated_tag_noise) against all the
  /// tags' together; a tag wider by more than 1.25 times gets its ratio (tag_scale_; event
  /// tag_sigma_widened).
  void learnTagScales(const EstimatorStatistics& learnt, EstimatorStatistics& stats);
  /// A tag's std over the learnt one (tag_scale_), 1 for the others.
  double tagScale(int tag) const {
    const auto it = tag_scale_.find(tag);
    return it == tag_scale_.end() ? 1.0 : it->second;
  }

  UwbPartParams params_;
  RangeFrontEnd front_;
  std::shared_ptr<const OccupancyMap> map_;
  std::string nlos_reason_;       ///< "nlos_<test>", built once
  uwb::ChiSquareGate pose_gate_;  ///< the pose test at k sigma (threshold k^2)
  std::vector<AcceptedRange> epoch_;
  /// A range the swarm's fitness weighs, with its likelihood under the mixture (the mixture at
  /// its link's chance of NLOS when it was weighed; unused without the mixture).
  struct UsedRange {
    AcceptedRange range;
    RangeMixture link;
  };
  std::vector<UsedRange> used_;  ///< the clean ones (bias removed), for the swarm's fitness
  RangeNoiseModel noise_;
  int epoch_flagged_ = 0;                ///< ranges of the open epoch that failed the NLOS test
  int nlos_streak_ = 0;                  ///< epochs in a row in which most ranges failed it
  std::optional<RangeMixture> mixture_;  ///< the learnt range likelihood, when in force
  NlosStateTrack nlos_state_;            ///< under the mixture: each link's NLOS state
  bool learn_at_lidar_ = false;          ///< the mixture is learnt by lidar-mcl's range probe
  std::deque<bool> recent_failed_;       ///< the NLOS test's verdicts on the last ranges
  /// Several tags: a tag whose ranges the learning found clearly wider than all the tags'
  /// together, its std over theirs; its ranges' std is the learnt one times it.
  std::map<int, double> tag_scale_;
};

/// The ranges judged at the filter's pose, without weighting it (lidar-mcl with range_model=1,
/// the fused filters' learning start): each accepted range's residual, its measured range minus
/// the distance predicted from the epoch's estimate. At the end the statistics carry the
/// residuals' std (estimated_range_sigma), each anchor's mean and std (estimated_noise) and,
/// when it explains them better than one Gaussian, the LOS / NLOS mixture fitted to them
/// (fitRangeMixture). The LiDAR places the pose where NLOS ranges cannot pull it, so the
/// mixture is read off a path the ranges did not bend.
class RangeModelProbe final : public EpochMeasurement {
 public:
  explicit RangeModelProbe(const EstimatorContext& context);
  bool take(const Event& event, EstimatorStatistics& stats) override;
  void weight(ParticleFilter&, EstimatorStatistics&) override {}
  double addLogLikelihood(double l, double, double, double) const override { return l; }
  void endEpoch(const PoseEstimate& estimate) override;
  void finish(EstimatorStatistics& stats) override;

 private:
  RangeFrontEnd front_;
  std::vector<AcceptedRange> epoch_;
  std::vector<std::pair<int, double>> residuals_;  ///< (anchor id, residual)
};

/// Bayes weights, then resampling by the filter's strategy when ESS / N falls below its
/// threshold (SIR).
class ResamplingStep final : public PosteriorStep {
 public:
  void apply(ParticleFilter& pf, const EpochFitness&, double, EstimatorStatistics&) override {
    pf.normalizeAndResample();
  }
};

/// PF-IBAS: the improved beetle swarm moves the particles towards the epoch's fitness (eq. 26
/// over the NLOS-cleaned ranges plus the LiDAR field); no particle is discarded, and each weight
/// is the fitness at its moved position (eq. 28), by default times the weight it carried into the
/// epoch. A collapsed swarm gets `min_spread` of jitter so that the estimate cannot freeze.
class SwarmStep final : public PosteriorStep {
 public:
  explicit SwarmStep(const SwarmPartParams& params);
  void beginEpoch(const ParticleFilter& pf) override;
  void apply(ParticleFilter& pf, const EpochFitness& fitness, double t,
             EstimatorStatistics& stats) override;
  void addArtifacts(std::vector<std::pair<std::string, std::string>>& out) const override;
  void epochKind(bool scan) override { scan_ = scan; }

 private:
  bool scan_ = true;
  /// Moves the particles; returns the planar spread of the moved swarm [m].
  double move(ParticleFilter& pf, const EpochFitness& fitness);
  /// The weights after the move (eq. 28 and the chosen variant).
  void reweight(ParticleFilter& pf, const EpochFitness& fitness, double spread,
                EstimatorStatistics& stats);

  SwarmPartParams params_;
  optim::BeetleSwarm swarm_;
  Eigen::MatrixXd positions_, start_;  ///< start_: posterior weights only
  ParticleEstimate predicted_;         ///< the cloud before this epoch's data (posterior)
  std::vector<double> prior_log_w_;    ///< the weights before this epoch's data
  optim::Box box_;                     ///< reused every epoch
  std::string spread_log_;             ///< "t,spread_xy" rows
};

}  // namespace uwbloc::loc
