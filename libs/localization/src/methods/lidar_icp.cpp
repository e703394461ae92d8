#include "uwbloc/localization/methods/lidar_icp.hpp"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/TPose2D.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/tfest/se2.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <iterator>
#include <vector>

namespace uwbloc::loc {

namespace {

// The points a scan is aligned to, each with its two neighbours along its own scan (NaN where it
// has none): the point-to-line refinement's lines.
struct LocalMap {
  mrpt::maps::CSimplePointsMap points;
  std::vector<std::array<Eigen::Vector2f, 2>> along;
};

}  // namespace

struct LidarIcp::Impl {
  struct Keyframe {
    Eigen::Vector2d position;             ///< where it was taken, in the estimate's frame
    double heading = 0;                   ///< the heading it was taken at [rad]
    double path = 0;                      ///< distance travelled when it was taken [m]
    std::vector<Eigen::Vector2f> points;  ///< its scan's points, in the estimate's frame
  };
  std::deque<Keyframe> keyframes;  ///< the local map's keyframes, oldest first
  double path = 0;                 ///< distance travelled from keyframe to keyframe [m]
  std::unique_ptr<LocalMap> map;   ///< their points

  // Adds a keyframe taken at `pose` (after `path` of travel), drops the keyframes the local map
  // no longer holds (but the newest), and rebuilds the map.
  void addKeyframe(const Eigen::Vector3d& pose, const mrpt::maps::CSimplePointsMap& scan,
                   const LidarIcpParams& p) {
    Keyframe kf{pose.head<2>(), pose.z(), path, std::vector<Eigen::Vector2f>(scan.size())};
    for (size_t i = 0; i < scan.size(); ++i) {
      float px, py, pz;
      scan.getPoint(i, px, py, pz);
      kf.points[i] = transformPoint(pose, Eigen::Vector2d(px, py)).cast<float>();
    }
    keyframes.push_back(std::move(kf));
    // Dropped: a keyframe out of the map's reach, or one the new keyframe replaces (taken within
    // half a keyframe's step of it, so that turning on the spot does not grow the map forever).
    const auto dropped = [&](const Keyframe& k) {
      const double apart = (k.position - pose.head<2>()).norm();
      return p.map_path <= 0 || p.map_radius <= 0 || path - k.path > p.map_path ||
             apart > p.map_radius ||
             (apart < 0.5 * p.kf_dist &&
              std::abs(wrapAngle(k.heading - pose.z())) < 0.5 * p.kf_angle_deg * M_PI / 180.0);
    };
    keyframes.erase(std::remove_if(keyframes.begin(), std::prev(keyframes.end()), dropped),
                    std::prev(keyframes.end()));
    // Every keyframe's every point: thinning the union to one point per `min_dist` cell cost
    // accuracy on every log measured (README, lidar-icp).
    map = std::make_unique<LocalMap>();
    const Eigen::Vector2f none = Eigen::Vector2f::Constant(NAN);
    for (const Keyframe& k : keyframes)
      for (size_t i = 0; i < k.points.size(); ++i) {
        map->points.insertPoint(k.points[i].x(), k.points[i].y(), 0.0f);
        map->along.push_back(
            {i > 0 ? k.points[i - 1] : none, i + 1 < k.points.size() ? k.points[i + 1] : none});
      }
  }
};

namespace {

// Every fifth keyframe point is a candidate, the candidates rotating each time the threshold
// shrinks (MRPT CICP's corresponding_points_decimation).
constexpr size_t kMatchDecimation = 5;
// A step below this [m, rad] means the current threshold has converged.
constexpr float kMinStep = 1e-6f;
// Fewer scan points (or point-to-line matches) than this and ICP is not tried.
constexpr size_t kMinPoints = 10;
// The spacing of the headings tried about a poor seed [deg]: ICP from the seed converges within
// about this much of the true heading on the logs measured (README, lidar-icp).
constexpr double kSearchStepDeg = 20.0;
// A searched heading that differs from the seed's fit by more than this is counted [deg].
constexpr double kSearchChangedDeg = 1.0;

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
    mrpt::math::TPose2D solved;
    // se2_l2 needs two pairs, and leaves `solved` at the origin when it fails.
    approaching = pairs.size() >= 2 && mrpt::tfest::se2_l2(pairs, solved);
    if (approaching) {
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

// Point-to-line refinement (PL-ICP's metric, Censi 2008) of the point-to-point answer: each scan
// point within `max_dist` of its nearest keyframe point is matched to the line through that point
// and its nearer neighbour along the keyframe scan (not farther than `max_dist` from it: no line
// across a gap), and the pose minimises the squared distances to those lines by Gauss-Newton,
// each residual Huber-weighted at 1.345 robust std. Point-to-point matching between scans whose
// rays fall on a wall at different places pulls the pose by the rays' spacing; the distance to
// the wall's line does not.
Eigen::Vector3d refinePointToLine(const LocalMap& map, const mrpt::maps::CSimplePointsMap& scan,
                                  Eigen::Vector3d x, double max_dist) {
  const Eigen::Vector3d start = x;
  if (map.points.size() < 2) return x;
  constexpr int kMaxIterations = 20;
  // Converged once a step moves less than this [m, rad]: a tenth of a millimetre at 10 m.
  constexpr double kLineStepXy = 1e-4, kLineStepTheta = 1e-5;
  constexpr double kDamping = 1e-6;  // of the normal matrix's trace, on its diagonal
  std::vector<double> abs_r;
  struct Row {
    Eigen::Vector3d j;
    double r;
  };
  std::vector<Row> rows;
  for (int it = 0; it < kMaxIterations; ++it) {
    rows.clear();
    const double c = std::cos(x.z()), s = std::sin(x.z());
    for (size_t i = 0; i < scan.size(); ++i) {
      float px, py, pz;
      scan.getPoint(i, px, py, pz);
      const Eigen::Vector2d p(px, py);
      const Eigen::Vector2d q(c * p.x() - s * p.y() + x.x(), s * p.x() + c * p.y() + x.y());
      float ox, oy, d2;
      const size_t k = map.points.kdTreeClosestPoint2D(static_cast<float>(q.x()),
                                                       static_cast<float>(q.y()), ox, oy, d2);
      if (d2 > max_dist * max_dist) continue;
      const Eigen::Vector2d a(ox, oy);
      Eigen::Vector2d b = a;
      double best = HUGE_VAL;
      for (const Eigen::Vector2f& nb : map.along[k]) {
        if (!nb.allFinite()) continue;
        const Eigen::Vector2d cand = nb.cast<double>();
        const double d = (cand - q).squaredNorm();
        if (d < best && (cand - a).norm() <= max_dist) best = d, b = cand;
      }
      if (!(best < HUGE_VAL)) continue;
      const Eigen::Vector2d t = (b - a).normalized();
      const Eigen::Vector2d n(-t.y(), t.x());
      const Eigen::Vector2d dp(-s * p.x() - c * p.y(), c * p.x() - s * p.y());
      rows.push_back({Eigen::Vector3d(n.x(), n.y(), n.dot(dp)), n.dot(q - a)});
    }
    if (rows.size() < kMinPoints) return x;
    abs_r.clear();
    for (const Row& r : rows) abs_r.push_back(std::abs(r.r));
    std::nth_element(abs_r.begin(), abs_r.begin() + abs_r.size() / 2, abs_r.end());
    const double k = 1.345 * std::max(1.4826 * abs_r[abs_r.size() / 2], 1e-4);
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const Row& r : rows) {
      const double w = std::abs(r.r) <= k ? 1.0 : k / std::abs(r.r);
      H += w * r.j * r.j.transpose();
      g += w * r.j * r.r;
    }
    // A direction the lines leave free (a corridor's length) keeps the point-to-point answer.
    H.diagonal().array() += kDamping * H.trace();
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) return start;
    x += step;
    if ((x - start).head<2>().norm() > max_dist) return start;
    if (step.head<2>().norm() < kLineStepXy && std::abs(step.z()) < kLineStepTheta) break;
  }
  return x;
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
      start_t_(context.startTime()),
      impl_(std::make_unique<Impl>()) {}

LidarIcp::~LidarIcp() = default;

std::optional<PoseEstimate> LidarIcp::doProcess(const Event& event) {
  if (const auto* odo = std::get_if<OdometryIncrement>(&event)) {
    if (odo->t <= start_t_)
      countRejection("odometry_before_start");
    else if (odo->delta.allFinite())
      odometry_since_keyframe_ = composePose(odometry_since_keyframe_, odo->delta);
    return std::nullopt;
  }
  const auto* scan = std::get_if<LaserScan>(&event);
  if (!scan) return std::nullopt;
  if (scan->t < start_t_) {
    countRejection("scan_before_start");
    return std::nullopt;
  }
  auto current = toPoints(*scan, params_);
  const bool usable = current->size() >= kMinPoints;
  // The pose of this scan relative to the keyframe: ICP against the local map, seeded by the
  // odometry, or the odometry.
  Eigen::Vector3d rel = odometry_since_keyframe_;
  if (!usable) {
    countRejection("scan_too_few_points");
  } else if (impl_->map) {
    const LocalMap& local = *impl_->map;
    const mrpt::maps::CSimplePointsMap& map = local.points;
    const Eigen::Vector3d seed = composePose(keyframe_pose_, odometry_since_keyframe_);
    IcpResult icp = alignScan(map, *current, seed, params_);
    // The odometry's heading is least trusted where it turned: there, and on a poor fit, the
    // headings about the seed are tried too.
    const bool turned =
        std::abs(odometry_since_keyframe_.z()) > params_.search_turn_deg * M_PI / 180.0;
    if ((icp.goodness < params_.min_goodness || turned) && params_.search_deg > 0) {
      IcpResult best = icp;
      for (double off = kSearchStepDeg; off <= params_.search_deg + 1e-9; off += kSearchStepDeg)
        for (double sign : {-1.0, 1.0}) {
          Eigen::Vector3d tried_seed = seed;
          tried_seed.z() += sign * off * M_PI / 180.0;
          const IcpResult tried = alignScan(map, *current, tried_seed, params_);
          if (tried.pose.allFinite() && tried.goodness > best.goodness) best = tried;
        }
      if (best.goodness >= params_.min_goodness && best.goodness > icp.goodness) {
        if (std::abs(wrapAngle(best.pose.z() - icp.pose.z())) > kSearchChangedDeg * M_PI / 180.0)
          ++stats_.events["icp_heading_searched"];
        icp = best;
      }
    }
    if (icp.goodness < params_.min_goodness || !icp.pose.allFinite())
      countRejection("icp_low_goodness");
    else
      rel = relativePose(keyframe_pose_,
                         params_.line_dist > 0
                             ? refinePointToLine(local, *current, icp.pose, params_.line_dist)
                             : icp.pose);
  }
  pose_ = composePose(keyframe_pose_, rel);
  const bool moved = rel.head<2>().norm() >= params_.kf_dist ||
                     std::abs(rel.z()) >= params_.kf_angle_deg * M_PI / 180.0;
  if (moved || !impl_->map) impl_->path += rel.head<2>().norm();  // travel, keyframe to keyframe
  if (usable && (!impl_->map || moved)) {
    impl_->addKeyframe(pose_, *current, params_);
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
