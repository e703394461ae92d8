#include "uwbloc/dataset/ground_truth.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/uwb/pose2.hpp"

namespace uwbloc::data {

std::vector<TimedPose> readGroundTruth(const std::string& path, GroundTruthFormat format,
                                       const std::vector<double>& step_times) {
  std::vector<TimedPose> out;
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
            std::atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz));
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
