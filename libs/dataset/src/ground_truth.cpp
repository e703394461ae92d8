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

void headingsInRadians(std::vector<TimedPose>& poses, const std::string& path,
                       std::vector<std::string>* warnings) {
  constexpr double kStretch = 0.1, kMaxSpan = 5.0;  // [m], [s]
  constexpr double kDegree = M_PI / 180.0, kTells = 5.0 * kDegree;
  // Each stretch's course and its heading halfway along (the shorter arc), read as radians and
  // as degrees.
  struct Stretch {
    double course, heading[2];
  };
  std::vector<Stretch> stretches;
  size_t from = 0;
  for (size_t i = 1; i < poses.size(); ++i) {
    const Eigen::Vector3d& a = poses[from].pose;
    const Eigen::Vector3d& b = poses[i].pose;
    const Eigen::Vector2d d = b.head<2>() - a.head<2>();
    if (poses[i].t - poses[from].t > kMaxSpan) {
      from = i;
      stretches.push_back({NAN, {NAN, NAN}});  // no turn across a stop or a gap
      continue;
    }
    if (d.norm() < kStretch) continue;
    Stretch s{std::atan2(d.y(), d.x()), {0.0, 0.0}};
    for (int k = 0; k < 2; ++k) {
      const double unit = k == 0 ? 1.0 : kDegree;
      s.heading[k] = unit * a.z() + 0.5 * wrapAngle(unit * (b.z() - a.z()));
    }
    stretches.push_back(s);
    from = i;
  }
  // The turn between two stretches, as the course turned and as the heading did in each reading
  // (axial: a change from forward to reverse turns the course by pi and the heading not).
  long tells = 0, degrees = 0;
  for (size_t i = 1; i < stretches.size(); ++i) {
    const Stretch &p = stretches[i - 1], &q = stretches[i];
    if (!std::isfinite(p.course) || !std::isfinite(q.course)) continue;
    const double turn = q.course - p.course;
    double off[2];
    for (int k = 0; k < 2; ++k)
      off[k] = std::abs(0.5 * wrapAngle(2.0 * (q.heading[k] - p.heading[k] - turn)));
    if (std::abs(off[0] - off[1]) < kTells) continue;  // the two readings turn alike
    ++tells;
    degrees += off[1] < off[0];
  }
  if (tells < 20 || degrees < 0.8 * static_cast<double>(tells)) return;
  for (auto& p : poses) p.pose.z() = wrapAngle(kDegree * p.pose.z());
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "%s: its headings are read as degrees: as radians they do not turn as the "
                "direction of travel does (as degrees they follow it in %ld of the %ld turns "
                "where the two readings differ)",
                path.c_str(), degrees, tells);
  if (warnings) warnings->push_back(buf);
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
  } else {
    headingsInRadians(out, path, warnings);
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
