#include "mrpt_scan.hpp"

#include <cmath>
#include <cstring>

namespace uwbloc::data {

bool byteAsBool(const bool& flag) {
  unsigned char byte = 0;
  std::memcpy(&byte, &flag, 1);
  return byte != 0;
}

loc::LaserScan fromMrpt(const mrpt::obs::CObservation2DRangeScan& obs, double t) {
  loc::LaserScan scan;
  scan.t = t;
  scan.sensor_pose << obs.sensorPose.x(), obs.sensorPose.y(), obs.sensorPose.yaw();
  scan.sensor_height = obs.sensorPose.z();
  const size_t n = obs.getScanSize();
  // MRPT spaces the rays by aperture / (N - 1) from -aperture/2 (right to left) or +aperture/2,
  // so a full circle repeats its first direction in the last ray.
  const bool right_to_left = byteAsBool(obs.rightToLeft);
  scan.angle_min = static_cast<float>(right_to_left ? -obs.aperture / 2 : obs.aperture / 2);
  scan.angle_increment =
      n > 1 ? static_cast<float>((right_to_left ? 1 : -1) * obs.aperture / (n - 1)) : 0.0f;
  scan.max_range = obs.maxRange;
  scan.ranges.resize(n);
  scan.valid.resize(n);
  for (size_t i = 0; i < n; ++i) {
    scan.ranges[i] = obs.getScanRange(i);
    scan.valid[i] = obs.getScanRangeValidity(i) ? 1 : 0;
  }
  return scan;
}

mrpt::obs::CObservation2DRangeScan toMrpt(const loc::LaserScan& s) {
  mrpt::obs::CObservation2DRangeScan obs;
  const size_t n = s.ranges.size();
  // A rawlog scan is symmetric about the sensor's axis: an asymmetric one (a CARMEN scan of 180
  // rays from -90 to +89 degrees) turns the sensor by its centre angle instead, the same rays.
  const double centre =
      n > 0 ? s.angle_min + 0.5 * static_cast<double>(n - 1) * s.angle_increment : 0.0;
  const double yaw =
      std::abs(centre) > 1e-6 ? loc::wrapAngle(s.sensor_pose.z() + centre) : s.sensor_pose.z();
  obs.sensorPose =
      mrpt::poses::CPose3D(s.sensor_pose.x(), s.sensor_pose.y(), s.sensor_height, yaw, 0, 0);
  obs.resizeScan(n);
  obs.rightToLeft = s.angle_increment >= 0.0f;
  obs.aperture = std::abs(s.angle_increment) * static_cast<float>(n > 1 ? n - 1 : 1);
  obs.maxRange = s.max_range;
  for (size_t i = 0; i < n; ++i) {
    obs.setScanRange(i, s.ranges[i]);
    obs.setScanRangeValidity(i, s.valid[i] != 0);
  }
  return obs;
}

}  // namespace uwbloc::data
