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
#pragma once

#include <memory>
#include <string>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/lidar/landmarks.hpp"
#include "uwbloc/localization/lidar/likelihood_field.hpp"
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
  RangeFrontEndParams front;           ///< UWB range checks; sigma is the range likelihood's std
  std::string nlos = "lidar";          ///< NLOS test: lidar, raycast or none
  double nlos_k = 3.0;                 ///< gate width in standard deviations
  std::string nlos_action = "reject";  ///< reject or downweight
  double downweight = 5.0;             ///< sigma factor for down-weighted ranges
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
    front.visit(v);
    v("nlos", nlos, "NLOS test on UWB ranges: lidar, raycast or none");
    v("nlos_k", nlos_k, "NLOS gate width [std]");
    v("nlos_action", nlos_action, "reject or downweight flagged ranges");
    v("downweight", downweight, "sigma factor for down-weighted ranges");
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
  void reset() override;

 public:
  std::vector<std::pair<std::string, std::string>> artifacts() const override;
  const LandmarkMap& landmarkMap() const { return landmark_map_; }

 private:
  void initialise();
  std::optional<PoseEstimate> output(double t);
  void updateRange(const AcceptedRange& r);

  PfLocalizerParams params_;
  EstimatorContext context_;
  bool use_lidar_, use_uwb_;
  ParticleFilter pf_;
  std::unique_ptr<LikelihoodField> field_;
  LandmarkExtractionParams extraction_;
  LandmarkMap landmark_map_;
};

}  // namespace uwbloc::loc
