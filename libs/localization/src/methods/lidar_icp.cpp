#include "uwbloc/localization/methods/lidar_icp.hpp"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/TPose2D.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/tfest/se2.h>

#include <cmath>

namespace uwbloc::loc {

struct LidarIcp::Impl {
  std::unique_ptr<mrpt::maps::CSimplePointsMap> previous;
};

namespace {

// Every fifth keyframe point is a candidate, the candidates rotating each time the threshold
// shrinks (MRPT CICP's corresponding_points_decimation).
constexpr size_t kMatchDecimation = 5;
// A step below this [m, rad] means the current threshold has converged.
constexpr float kMinStep = 1e-6f;

struct IcpResult {
  Eigen::Vector3d pose;  ///< the scan's pose in the keyframe's frame
  double goodness = 0;   ///< fraction of the scan's points matched at the last iteration
};

// Classic point-to-point ICP, the loop of MRPT's CICP (icpClassic) without the covariance it
// also computes and lidar-icp never used: each scan point, placed at the current pose, is
// matched to its nearest keyframe point within a distance threshold (MRPT's kd-tree
// matching); the SE(2) transform that best aligns the pairs follows in closed form
// (mrpt::tfest::se2_l2). When the pose stops moving, the threshold shrinks by `alfa`, until it
// falls below `smallest_dist` or `max_iterations` is spent. Linking MRPT's ICP would pull
// mrpt-slam, and through it mrpt-vision, Qt and FFmpeg, into every uwbloc process: 117 more
// shared libraries, a tenth of a second at each start.
IcpResult alignScan(const mrpt::maps::CSimplePointsMap& keyframe,
                    const mrpt::maps::CSimplePointsMap& scan, const Eigen::Vector3d& guess,
                    const LidarIcpParams& p) {
  const float alfa = static_cast<float>(p.alfa);
  const float smallest = static_cast<float>(p.smallest_dist);
  mrpt::maps::TMatchingParams match;
  match.maxDistForCorrespondence = static_cast<float>(p.threshold_dist);
  match.maxAngularDistForCorrespondence = static_cast<float>(p.threshold_ang_deg * M_PI / 180.0);
  match.onlyKeepTheClosest = true;
  match.onlyUniqueRobust = false;
  match.decimation_other_map_points = kMatchDecimation;
  match.offset_other_map_points = 0;
  mrpt::maps::TMatchingExtraResults extra;
  mrpt::tfest::TMatchingPairList pairs;
  mrpt::poses::CPose2D pose(guess.x(), guess.y(), guess.z()), last;
  int iterations = 0;
  bool approaching = true;
  do {
    match.angularDistPivotPoint = mrpt::math::TPoint3D(pose.x(), pose.y(), 0.0);
    keyframe.determineMatching2D(&scan, pose, pairs, match, extra);
    approaching = !pairs.empty();
    if (approaching) {
      mrpt::math::TPose2D solved;
      mrpt::tfest::se2_l2(pairs, solved);
      pose = mrpt::poses::CPose2D(solved);
      const bool converged = std::abs(last.x() - pose.x()) <= kMinStep &&
                             std::abs(last.y() - pose.y()) <= kMinStep &&
                             std::abs(mrpt::math::wrapToPi(last.phi() - pose.phi())) <= kMinStep;
      if (converged) {
        match.maxDistForCorrespondence *= alfa;
        match.maxAngularDistForCorrespondence *= alfa;
        approaching = match.maxDistForCorrespondence >= smallest;
        if (++match.offset_other_map_points >= kMatchDecimation) match.offset_other_map_points = 0;
      }
      last = pose;
    }
    ++iterations;
    const bool spent = iterations >= p.max_iterations;
    if (spent && match.maxDistForCorrespondence > smallest) match.maxDistForCorrespondence *= alfa;
    if (spent ? !(match.maxDistForCorrespondence > smallest) : !approaching) break;
  } while (true);
  return {{pose.x(), pose.y(), pose.phi()}, extra.correspondencesRatio};
}

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
      impl_(std::make_unique<Impl>()) {}

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
    const IcpResult icp = alignScan(*impl_->previous, *current, odometry_since_keyframe_, params_);
    if (icp.goodness < params_.min_goodness || !icp.pose.allFinite())
      countRejection("icp_low_goodness");
    else
      rel = icp.pose;
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
