#include "uwbloc/dataset/carmen_import.hpp"

#include <mrpt/io/CFileGZInputStream.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>

#include "odometry_poses.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/localization/params.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

std::string readAll(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throwInputError(path, 0, "log not found");
  mrpt::io::CFileGZInputStream in;  // also reads uncompressed files
  if (!in.open(path)) throwInputError(path, 0, "cannot open log");
  std::string text;
  char buf[65536];
  for (;;) {
    const size_t n = in.Read(buf, sizeof buf);
    if (n == 0) break;
    text.append(buf, n);
  }
  return text;
}

// FLASER n r1..rn ...: a scan of n rays, right to left from -90 degrees; readings of 80 m and
// more are no returns. The rays are a whole fraction of 180 degrees apart: an odd n spans
// -90..+90 (181 rays at 1 degree, 361 at 0.5), an even n stops one step short of +90 (180 rays
// at 1 degree, -90..+89). Measured on intel and aces (180 rays): with 180/179 degrees between
// rays, lidar-icp's turns came out 0.33 % and 0.67 % larger than the reference's; at 1 degree,
// -0.23 % and +0.10 % (README, lidar-icp).
template <class Num>
loc::LaserScan flaserScan(size_t n, double t, Num& num) {
  loc::LaserScan scan;
  scan.t = t;
  scan.max_range = 81.0f;
  scan.angle_min = static_cast<float>(-M_PI / 2);
  const size_t steps = n % 2 == 1 ? n - 1 : n;
  scan.angle_increment = static_cast<float>(steps > 0 ? M_PI / static_cast<double>(steps) : 0.0);
  scan.ranges.resize(n);
  scan.valid.resize(n);
  for (size_t i = 0; i < n; ++i) {
    scan.ranges[i] = static_cast<float>(num(1 + i, "range"));
    scan.valid[i] = scan.ranges[i] > 0.0f && scan.ranges[i] < 80.0f;
  }
  return scan;
}

struct CarmenLog {
  std::vector<loc::Event> events;       ///< scans and odometry increments, in time order
  std::vector<TimedPose> reference;     ///< the FLASER lines' corrected poses
  std::map<std::string, long> skipped;  ///< lines left out, by reason
};

bool samePose(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return (a - b).cwiseAbs().maxCoeff() < 1e-6;
}

// The odometry of a "corrected" CARMEN log. Such logs repeat each FLASER line's corrected pose in
// an ODOM line right after it, stamped 0 or with a garbage stamp; chaining those copies into the
// odometry would teleport the robot onto the reference and back at every scan. The rule:
//  - an ODOM line whose pose equals the corrected pose of the FLASER line before it is a copy;
//  - an ODOM line with a non-finite or negative stamp, or one earlier than the last kept ODOM
//    line's, is not a later reading;
// both are dropped and counted. Without ODOM lines the FLASER lines' own odometry fields are used,
// unless they too equal the corrected pose (then the log has no independent odometry).
class CarmenOdometry {
 public:
  explicit CarmenOdometry(CarmenLog& log) : log_(log) {}
  void flaser(const Eigen::Vector3d& corrected) { last_corrected_ = corrected; }
  void odom(double t, const Eigen::Vector3d& pose) {
    if (last_corrected_ && samePose(pose, *last_corrected_))
      return skip("odom_corrected_pose_copy");
    if (const char* problem = timestampProblem(t)) return skip(std::string("odom_") + problem);
    if (!pose.allFinite()) return skip("odom_non_finite_pose");
    if (!odometry_.add(t, pose, log_.events)) return skip("odom_out_of_order");
  }

 private:
  void skip(const std::string& reason) { ++log_.skipped[reason]; }
  CarmenLog& log_;
  OdometryFromPoses odometry_;
  std::optional<Eigen::Vector3d> last_corrected_;
};

// The scans, odometry and corrected poses of a CARMEN log.
CarmenLog parseCarmen(const std::string& log_path) {
  CarmenLog log;
  const std::string text = readAll(log_path);
  std::istringstream lines(text);
  std::string line;
  int number = 0;
  const bool has_odom_lines = text.find("\nODOM ") != std::string::npos;
  CarmenOdometry odometry(log);
  while (std::getline(lines, line)) {
    ++number;
    std::istringstream in(line);
    std::string kind;
    in >> kind;
    std::vector<std::string> f;
    for (std::string x; in >> x;) f.push_back(x);
    auto num = [&](size_t i, const char* field) {
      if (i >= f.size())
        throwInputError(log_path, number, std::string("missing field '") + field + "'");
      return parseNumber(f[i], log_path, number, field);
    };
    if (kind == "ODOM") {
      // ODOM x y theta tv rv accel ipc_timestamp ipc_hostname logger_timestamp
      odometry.odom(num(6, "ipc_timestamp"), {num(0, "x"), num(1, "y"), num(2, "theta")});
    } else if (kind == "FLASER") {
      // FLASER n r1..rn x y theta odom_x odom_y odom_theta ipc_timestamp ipc_hostname logger_ts
      const double readings = num(0, "num_readings");
      if (!(readings >= 1 && readings <= 1e5) || readings != std::floor(readings))
        throwInputError(log_path, number,
                        "field 'num_readings': expected an integer in [1, 100000], got " +
                            loc::quoteToken(f[0]));
      const auto n = static_cast<size_t>(readings);
      if (f.size() < n + 10) throwInputError(log_path, number, "FLASER line too short");
      const double t = num(n + 7, "ipc_timestamp");
      const Eigen::Vector3d corrected(num(n + 1, "x"), num(n + 2, "y"), num(n + 3, "theta"));
      const Eigen::Vector3d own(num(n + 4, "odom_x"), num(n + 5, "odom_y"),
                                num(n + 6, "odom_theta"));
      if (const char* problem = timestampProblem(t)) {
        ++log.skipped[std::string("flaser_") + problem];
        continue;
      }
      if (!corrected.allFinite()) {
        ++log.skipped["flaser_non_finite_pose"];
        continue;
      }
      log.events.emplace_back(flaserScan(n, t, num));
      log.reference.push_back({t, corrected});
      if (!has_odom_lines) {
        if (samePose(own, corrected))
          ++log.skipped["flaser_odometry_is_the_corrected_pose"];
        else
          odometry.odom(t, own);
      }
      odometry.flaser(corrected);
    }
  }
  if (log.reference.empty()) throwInputError(log_path, 0, "no FLASER lines");
  loc::sortByTime(log.events);
  std::stable_sort(log.reference.begin(), log.reference.end(),
                   [](const TimedPose& a, const TimedPose& b) { return a.t < b.t; });
  return log;
}

}  // namespace

ImportSummary importCarmen(const std::string& log_path, const std::string& out_dir) {
  const CarmenLog log = parseCarmen(log_path);
  const auto& events = log.events;
  const auto& reference = log.reference;
  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "carmen.rawlog").string(), events);
  writeFileAtomic((out / "reference.txt").string(), formatTimeXyPhi(reference));
  std::string name = fs::path(log_path).filename().string();
  for (const char* ext : {".gz", ".log"})
    if (name.size() > std::string(ext).size() &&
        name.substr(name.size() - std::string(ext).size()) == ext)
      name = name.substr(0, name.size() - std::string(ext).size());
  ManifestDraft m;
  m.comments = {"Imported by 'uwbloc import carmen' from " + fs::absolute(log_path).string(),
                "The reference is the log's SLAM-corrected laser pose, not independent ground "
                "truth.",
                "No anchors: add some with 'uwbloc augment'. This manifest lists a placeholder "
                "anchor."};
  m.name = "carmen_" + name;
  m.rawlog = "carmen.rawlog";
  m.ground_truth = "reference.txt";
  m.ground_truth_format = GroundTruthFormat::kTimeXyPhi;
  m.anchors = {{1, {0.0, 0.0, 2.0}}};
  ImportSummary summary;
  summary.manifest = writeManifest(out_dir, m);
  for (const auto& e : events) summary.scans += std::holds_alternative<loc::LaserScan>(e);
  summary.ground_truth_rows = static_cast<long>(reference.size());
  summary.skipped = log.skipped;
  if (const auto w = collapsedTimeWarning(events)) summary.notes.push_back("WARNING: " + *w);
  return summary;
}

}  // namespace uwbloc::data
