// uwb-ins: UWB/INS fusion, the set-up of the H∞ cubature and improved Sage-Husa papers: an
// extended Kalman filter over the planar strapdown state [p(2) v(2) ψ b_g b_a(2)] (ins.hpp),
// predicted by every IMU sample (the mechanisation and its Jacobian; white accelerometer and
// gyro noise, bias random walks), and corrected
//   - mode=ranges (tight, the H∞ paper's): by each range, h = |p + R(ψ) l - anchor| with the
//     tag's lever arm l, behind uwb-ekf's chi-square gate;
//   - mode=fix (loose, the Sage-Husa paper's): by each epoch's Gauss-Newton fix of the tag,
//     H = [I R'(ψ) l ...], R the fix's covariance, behind a 2-dof gate;
//   - filter=ckf: the same with the cubature rule (kalman/cubature.hpp): the points through the
//     mechanisation for the time update and through the range (or fix) model for the update;
//     `hinf` makes the update the H∞ CKF's and `robust` adds the IGG-III factor above the NLOS
//     threshold (point_filters.hpp): uwb-ins-ckf and uwb-ins-ickf, the H∞ paper's CKF and ICKF
//     in its UWB/INS set-up (without the Sage-Husa statistics of uwb-iahckf);
//   - by ZUPT (v = 0) and ZARU (the gyro bias equals the mean rate) pseudo-measurements
//     whenever the stationarity detector says so (ins.hpp), each with its own small noise.
// It starts at the first consistent fix (at the start pose when the run has one), with the start
// pose's heading or, without one, heading unknown (σ = π): the heading is then observed from
// the motion. Between ranges (a UWB gap) the INS carries the estimate alone; an estimate is
// given at each range and at each ZUPT.
#pragma once

#include <Eigen/Core>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/ins.hpp"
#include "uwbloc/localization/kalman/kalman.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

enum class InsMode { kRanges, kFix };
constexpr std::array<EnumName<InsMode>, 2> enumNames(InsMode) {
  return {{{InsMode::kRanges, "ranges"}, {InsMode::kFix, "fix"}}};
}
enum class InsFilter { kEkf, kCkf };
constexpr std::array<EnumName<InsFilter>, 2> enumNames(InsFilter) {
  return {{{InsFilter::kEkf, "ekf"}, {InsFilter::kCkf, "ckf"}}};
}

struct UwbInsParams {
  RangeFrontEndParams front;
  InsMode mode = InsMode::kRanges;
  AutoDouble epoch_window;          ///< epoch window of the fixes [s]; auto: the data's rate
  double accel_noise = 0.1;         ///< accelerometer white noise [m/s^2 per sqrt(Hz)]
  double gyro_noise = 0.01;         ///< gyro white noise [rad/s per sqrt(Hz)]
  double accel_bias_walk = 0.005;   ///< [m/s^2 per sqrt(s)]
  double gyro_bias_walk = 0.0005;   ///< [rad/s per sqrt(s)]
  double gate = 9.0;                ///< chi-square gate per range (fix: scaled to 2 dof)
  int max_gated = 12;               ///< consecutive gated updates before re-initialising
  double init_residual = 0.5;       ///< largest residual norm of the initial fix [m]
  bool zupt = true;                 ///< zero-velocity updates
  bool zaru = true;                 ///< zero-angular-rate updates
  double still_window = 0.3;        ///< detector window [s]
  double still_acc = 0.1;           ///< std of |f| below which the IMU is still [m/s^2]
  double still_gyro = 0.02;         ///< std of the rate below which it is still [rad/s]
  double still_rate = 0.02;         ///< |mean rate - bias| below which it is not turning [rad/s]
  InsFilter filter = InsFilter::kEkf;  ///< EKF, or cubature (points through the mechanisation)
  double hinf = 0.0;                ///< ckf: the H∞ bound on the position (point_filters.hpp)
  bool robust = false;              ///< ckf, ranges: IGG-III factor above nlos_threshold
  double k0 = 2.0, k1 = 5.0;        ///< IGG-III thresholds [std]
  double nlos_threshold = 0.24;     ///< [m]

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("mode", mode, "ranges: update with each range (tight); fix: with each epoch's fix (loose)");
    v("window", epoch_window, "epoch window of the fixes [s], or auto");
    v("accel_noise", accel_noise, "accelerometer white noise [m/s^2/sqrt(Hz)]");
    v("gyro_noise", gyro_noise, "gyro white noise [rad/s/sqrt(Hz)]");
    v("accel_bias_walk", accel_bias_walk, "accelerometer bias random walk [m/s^2/sqrt(s)]");
    v("gyro_bias_walk", gyro_bias_walk, "gyro bias random walk [rad/s/sqrt(s)]");
    v("gate", gate, "chi-square gate on each range innovation (1 dof)");
    v("max_gated", max_gated, "consecutive gated updates before re-initialising");
    v("init_residual", init_residual, "largest residual norm of the initial fix [m]");
    v("zupt", zupt, "zero-velocity updates when the IMU is still");
    v("zaru", zaru, "zero-angular-rate updates when still and not turning");
    v("still_window", still_window, "stationarity detector window [s]");
    v("still_acc", still_acc, "std of |accel| under which the IMU counts as still [m/s^2]");
    v("still_gyro", still_gyro, "std of the yaw rate under which it counts as still [rad/s]");
    v("still_rate", still_rate, "largest |mean rate - bias| that counts as not turning [rad/s]");
    v("filter", filter, "ekf: extended KF; ckf: cubature KF (the H-infinity paper's family)");
    v("hinf", hinf, "ckf: H-infinity bound over the smallest feasible (0 = plain CKF)");
    v("robust", robust, "ckf with ranges: IGG-III factor on R beyond nlos_threshold");
    v("k0", k0, "IGG-III: normalised innovations up to k0 keep R");
    v("k1", k1, "IGG-III: beyond k1 the range is dropped");
    v("nlos_threshold", nlos_threshold, "innovations within this are never down-weighted [m]");
  }
};

class UwbIns : public UwbEstimator {
 public:
  UwbIns(const UwbInsParams& params, const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  void reset() override;

 private:
  using Vec8 = Eigen::Matrix<double, 8, 1>;
  using Mat8 = Eigen::Matrix<double, 8, 8>;
  std::optional<PoseEstimate> onImu(const ImuSample& imu);
  bool initialise(const AcceptedRange& r);
  bool updateRange(const AcceptedRange& r);
  bool updateRangeCubature(const AcceptedRange& r);
  bool updateFix(const uwb::Fix& fix, const Eigen::Vector3d& tag_on_robot);
  /// A linear pseudo-measurement z = H x + v (ZUPT, ZARU), without a gate.
  template <int M>
  void pseudoUpdate(const Eigen::Matrix<double, M, 1>& y, const Eigen::Matrix<double, M, 8>& h,
                    const Eigen::Matrix<double, M, M>& r);
  void correct(const Vec8& dx);
  PoseEstimate output() const;

  UwbInsParams params_;
  std::optional<Eigen::Vector3d> start_pose_;
  InsState s_;
  Mat8 p_ = Mat8::Identity();
  double t_ = 0.0;
  bool initialised_ = false;
  int gated_in_a_row_ = 0;
  Eigen::Vector3d tag_on_robot_ = Eigen::Vector3d::Zero();
  EpochBuffer epochs_;
  StationarityDetector detector_;
};

}  // namespace uwbloc::loc
