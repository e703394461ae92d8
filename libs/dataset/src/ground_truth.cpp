#include "uwbloc/dataset/ground_truth.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::data {

namespace {
// The heading (rotation about z) of the quaternion (x, y, z, w), and how far it tilts the
// vertical [rad].
double yawOf(double x, double y, double z, double w) {
  return std::atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}
double tiltOf(double x, double y, double z, double w) {
  const double n2 = x * x + y * y + z * z + w * w;
  return n2 > 0.0 ? std::acos(std::clamp(1.0 - 2.0 * (x * x + y * y) / n2, -1.0, 1.0)) : 0.0;
}
}  // namespace

std::vector<double> planarHeadings(const std::vector<Eigen::Vector4d>& quaternions,
                                   const std::string& path, std::vector<std::string>* warnings) {
  std::vector<double> as_written, scalar_first, yaw;
  for (const auto& q : quaternions) {
    as_written.push_back(tiltOf(q[0], q[1], q[2], q[3]));
    scalar_first.push_back(tiltOf(q[1], q[2], q[3], q[0]));
    yaw.push_back(yawOf(q[0], q[1], q[2], q[3]));
  }
  if (quaternions.empty()) return yaw;
  const double tilt = loc::medianOf(as_written), tilt_first = loc::medianOf(scalar_first);
  const double deg = 180.0 / M_PI;
  if (tilt <= 45.0 / deg) return yaw;
  const bool scalar_first_fits = tilt_first < 15.0 / deg;
  if (scalar_first_fits)
    for (size_t i = 0; i < quaternions.size(); ++i) {
      const auto& q = quaternions[i];
      yaw[i] = yawOf(q[1], q[2], q[3], q[0]);
    }
  char buf[500];
  std::snprintf(buf, sizeof buf,
                "%s: its quaternions tilt the vertical a median %.0f deg read as TUM's 'qx qy qz "
                "qw', which a planar robot does not, and %.0f deg read as 'qw qx qy qz' (the "
                "scalar first): %s",
                path.c_str(), tilt * deg, tilt_first * deg,
                scalar_first_fits
                    ? "they are read scalar first"
                    : "their heading, the rotation about z, is not the robot's (a y-up frame?), "
                      "and the heading scores from it cannot be trusted");
  if (warnings) warnings->push_back(buf);
  return yaw;
}

std::vector<TimedPose> readGroundTruth(const std::string& path, GroundTruthFormat format,
                                       const std::vector<double>& step_times,
                                       std::vector<std::string>* warnings) {
  std::vector<TimedPose> out;
  std::vector<Eigen::Vector4d> quaternions;  // TUM: each row's qx qy qz qw as written
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    TimedPose p;
    switch (format) {
      case GroundTruthFormat::kStepXyPhi: {
        if (f.size() < 4) throwInputError(path, line, "expected 'step x y phi'");
        const double step = parseNumber(f[0], path, line, "step");
        if (step < 0 || step != std::floor(step) || step >= static_cast<double>(step_times.size()))
          throwInputError(path, line,
                          "step " + f[0] + " is not a step of the rawlog (it has " +
                              std::to_string(step_times.size()) + ")");
        p.t = step_times[static_cast<size_t>(step)];
        p.pose << parseNumber(f[1], path, line, "x"), parseNumber(f[2], path, line, "y"),
            parseNumber(f[3], path, line, "phi");
        break;
      }
      case GroundTruthFormat::kTimeXyPhi:
        if (f.size() != 4)
          throwInputError(
              path, line,
              "expected 'time x y phi', got " + std::to_string(f.size()) + " fields" +
                  (f.size() == 8 ? " (a TUM file? set ground_truth_format = tum)" : ""));
        p.t = parseNumber(f[0], path, line, "time");
        p.pose << parseNumber(f[1], path, line, "x"), parseNumber(f[2], path, line, "y"),
            parseNumber(f[3], path, line, "phi");
        break;
      case GroundTruthFormat::kTum: {
        if (f.size() < 8) throwInputError(path, line, "expected 't x y z qx qy qz qw'");
        p.t = parseNumber(f[0], path, line, "t");
        const double qx = parseNumber(f[4], path, line, "qx");
        const double qy = parseNumber(f[5], path, line, "qy");
        const double qz = parseNumber(f[6], path, line, "qz");
        const double qw = parseNumber(f[7], path, line, "qw");
        p.pose << parseNumber(f[1], path, line, "x"), parseNumber(f[2], path, line, "y"),
            yawOf(qx, qy, qz, qw);
        quaternions.emplace_back(qx, qy, qz, qw);
        break;
      }
      case GroundTruthFormat::kNone:
        throwInputError(path, line, "no ground-truth format given");
    }
    if (!p.pose.allFinite() || !std::isfinite(p.t)) throwInputError(path, line, "non-finite value");
    if (p.t < 0.0) throwInputError(path, line, "negative time");
    if (!out.empty() && p.t < out.back().t) throwInputError(path, line, "time goes backwards");
    out.push_back(p);
  });
  if (out.empty()) throwInputError(path, 0, "no ground-truth rows");
  if (!quaternions.empty()) {
    const auto yaw = planarHeadings(quaternions, path, warnings);
    for (size_t i = 0; i < out.size(); ++i) out[i].pose.z() = yaw[i];
  }
  return out;
}

std::string formatTum(const std::vector<TimedPose>& poses) {
  std::string out;
  char buf[256];
  for (const auto& p : poses) {
    // Times to the nanosecond: a Unix time's double keeps 17 digits, and a time rounded to the
    // microsecond can miss the reference sample it was estimated at.
    std::snprintf(buf, sizeof buf, "%.9f %.6f %.6f 0 0 0 %.9f %.9f\n", p.t, p.pose.x(), p.pose.y(),
                  std::sin(p.pose.z() / 2.0), std::cos(p.pose.z() / 2.0));
    out += buf;
  }
  return out;
}

std::optional<Eigen::Vector3d> interpolateGroundTruth(const std::vector<TimedPose>& gt, double t,
                                                      double max_gap) {
  // Written to be false for a NaN t too (lower_bound would then give begin()).
  if (gt.empty() || !(t >= gt.front().t && t <= gt.back().t)) return std::nullopt;
  auto hi = std::lower_bound(gt.begin(), gt.end(), t,
                             [](const TimedPose& p, double v) { return p.t < v; });
  if (hi->t == t) return hi->pose;
  const auto lo = hi - 1;
  const double span = hi->t - lo->t;
  if (span > max_gap || span <= 0.0) return std::nullopt;
  const double a = (t - lo->t) / span;
  Eigen::Vector3d p = lo->pose + a * (hi->pose - lo->pose);
  p.z() = uwbloc::wrapAngle(lo->pose.z() + a * uwbloc::wrapAngle(hi->pose.z() - lo->pose.z()));
  return p;
}

}  // namespace uwbloc::data
