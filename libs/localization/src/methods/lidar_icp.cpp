#include "uwbloc/localization/methods/lidar_icp.hpp"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/poses/CPosePDF.h>
#include <mrpt/slam/CICP.h>

#include <cmath>

namespace uwbloc::loc {

struct LidarIcp::Impl {
  mrpt::slam::CICP icp;
  std::unique_ptr<mrpt::maps::CSimplePointsMap> previous;
};

namespace {

// Scan endpoints in the robot frame as an MRPT point map.
std::unique_ptr<mrpt::maps::CSimplePointsMap> toPoints(const LaserScan& scan,
                                                       const LidarIcpParams& p) {
  auto map = std::make_unique<mrpt::maps::CSimplePointsMap>();
  forEachScanEndpoint(scan, static_cast<size_t>(std::max(1, p.decimation)), p.min_range,
                      std::nextafter(p.max_range, HUGE_VAL),  // max_range itself is a return
                      [&](size_t, const Eigen::Vector2d& q) {
                        map->insertPoint(static_cast<float>(q.x()), static_cast<float>(q.y()),
                                         0.0f);
                      });
  return map;
}

}  // namespace

LidarIcp::LidarIcp(const LidarIcpParams& params, const EstimatorContext& context)
    : params_(params),
      pose_(context.initial_pose.value_or(Eigen::Vector3d::Zero())),
      keyframe_pose_(pose_),
      impl_(std::make_unique<Impl>()) {
  auto& o = impl_->icp.options;
  o.maxIterations = static_cast<unsigned>(params_.max_iterations);
  o.thresholdDist = params_.threshold_dist;
  o.thresholdAng = params_.threshold_ang_deg * M_PI / 180.0;
  o.ALFA = params_.alfa;
  o.smallestThresholdDist = params_.smallest_dist;
}

LidarIcp::~LidarIcp() = default;

std::optional<PoseEstimate> LidarIcp::doProcess(const Event& event) {
  if (const auto* odo = std::get_if<OdometryIncrement>(&event)) {
    if (odo->delta.allFinite())
      odometry_since_keyframe_ = composePose(odometry_since_keyframe_, odo->delta);
    return std::nullopt;
  }
  const auto* scan = std::get_if<LaserScan>(&event);
  if (!scan) return std::nullopt;
  auto current = toPoints(*scan, params_);
  const bool usable = current->size() >= 10;
  // The pose of this scan relative to the keyframe: ICP seeded by the odometry, or the odometry.
  Eigen::Vector3d rel = odometry_since_keyframe_;
  if (!usable) {
    countRejection("scan_too_few_points");
  } else if (impl_->previous) {
    const auto& g = odometry_since_keyframe_;
    mrpt::slam::CICP::TReturnInfo info;
    const auto pdf = impl_->icp.Align(impl_->previous.get(), current.get(),
                                      mrpt::poses::CPose2D(g.x(), g.y(), g.z()), info);
    const auto mean = pdf->getMeanVal();
    const Eigen::Vector3d icp(mean.x(), mean.y(), mean.phi());
    if (info.goodness < params_.min_goodness || !icp.allFinite())
      countRejection("icp_low_goodness");
    else
      rel = icp;
  }
  pose_ = composePose(keyframe_pose_, rel);
  const bool moved = rel.head<2>().norm() >= params_.kf_dist ||
                     std::abs(rel.z()) >= params_.kf_angle_deg * M_PI / 180.0;
  if (usable && (!impl_->previous || moved)) {
    impl_->previous = std::move(current);
    keyframe_pose_ = pose_;
    odometry_since_keyframe_ = Eigen::Vector3d::Zero();
    // Re-seed from the estimate: the odometry since the keyframe restarts at zero.
  } else if (!usable && moved) {
    keyframe_pose_ = pose_;
    odometry_since_keyframe_ = Eigen::Vector3d::Zero();
  } else {
    // Keep integrating odometry from the keyframe, but start from ICP's answer.
    odometry_since_keyframe_ = rel;
  }
  PoseEstimate est;
  est.t = scan->t;
  est.pose = pose_;
  return est;
}

}  // namespace uwbloc::loc
