// Dataset manifest: one small INI file naming the pieces of one dataset.
//
//   [dataset]
//   name                = mrpt_uwb_demo
//   rawlog              = path                 (required)
//   ground_truth        = path                 (optional)
//   ground_truth_format = step_xyphi | time_xyphi | tum
//   gt_max_gap          = 1.0                  (longest ground-truth gap to interpolate over [s])
//   gt_time_offset      = 0.0                  (added to every reference stamp [s]: its clock's lag
//                                               behind the recording's)
//   reference_heading   = true                 (false: the reference's heading is not measured,
//                                               so no heading error is scored)
//   map                 = path                 (optional)
//   range_features      = path                 (optional side file, see hanyang_import.hpp)
//
//   [anchors]
//   anchors_csv = path                         (id,x,y,z rows), and/or MRPT's form:
//   beacon_001_ID = 1
//   beacon_001_X = 0.21   beacon_001_Y = -0.55   beacon_001_Z = 1.94
//   # Pose of the map/GT frame's origin expressed in the anchor frame: "x y yaw_deg".
//   # An anchor p_a maps to p_gt = R(yaw)^T (p_a - (x, y)); z is unchanged.
//   gt_origin_in_anchor_frame = 2 4 0
//
//   bias_csv = path                            (optional: per-link range bias, see RangeBias)
//
//   [tag]                                      (optional: overrides the rawlog's sensor pose)
//   height = 1.12    lever_arm_x = 0.16    lever_arm_y = 0
//   # Several tags on the robot: one key per tag id, its position on the robot "x y z" [m]
//   # (x forward, y left, z up: z is the tag's height). Ranges from a listed tag are the
//   # robot's own; ranges from an unlisted tag other than 0 come from a mobile node.
//   tag_0 = -0.0689 -0.1423 0.965    tag_1 = -0.0750 0.1402 0.966
//
//   [uwb]                                      (optional)
//   sigma = 0.10                               range noise measured on this dataset [m]: the
//                                              default `sigma` of every UWB method on it
//
//   [bounds]                                   (optional: allows Cramér–Rao bounds)
//   range_sigma = 0.1                          LOS range noise std [m]
//   accel_psd = 0.1                            CV motion noise for the posterior bound [m^2/s^3]
//   motion = cv | odometry                     motion model of the posterior bound
//   odom_sigma_xy_per_m = 0.02                 odometry noise (motion = odometry)
//   odom_sigma_theta_per_rad = 0.02
//   odom_sigma_theta_per_m = 0.005
//
// Paths are relative to the manifest's folder; a path starting with "${DATA}/" is relative to
// the data directory (see data_dir.hpp). Unknown keys are errors that name the line.
#pragma once

#include <Eigen/Core>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/uwb/types.hpp"

namespace uwbloc::data {

enum class GroundTruthFormat { kNone, kStepXyPhi, kTimeXyPhi, kTum };

struct BoundsSpec {
  double range_sigma = 0.1;                ///< LOS range noise std [m]
  double accel_psd = 0.1;                  ///< white-acceleration density of the CV model [m^2/s^3]
  std::string motion = "cv";               ///< motion model of the posterior bound: cv or odometry
  double odom_sigma_xy_per_m = 0.02;       ///< odometry translation noise per metre
  double odom_sigma_theta_per_rad = 0.02;  ///< odometry rotation noise per radian
  double odom_sigma_theta_per_m = 0.005;   ///< odometry rotation noise per metre [rad/m]
};

/// A range bias: measured = (1 + scale) * true + bias, for one anchor and one tag (or every tag).
struct RangeBias {
  int anchor_id = 0;
  std::optional<int> tag_id;  ///< nothing: every tag
  double bias = 0.0;          ///< [m]
  double scale = 0.0;         ///< dimensionless
  double sigma = 0.0;         ///< range noise std after the correction [m] (0: not estimated)
  long samples = 0;           ///< ranges the estimate came from (0: not known)
};

/// Reads a bias CSV: "anchor_id,tag_id,bias[,scale[,sigma[,samples]]]" rows, tag_id "*" for every
/// tag (a header row is allowed). Throws InputError naming the file and line.
std::vector<RangeBias> loadBiasCsv(const std::string& path);
std::string formatBiasCsv(const std::vector<RangeBias>& biases);
/// The bias that applies to (anchor, tag): the tag's own row before an every-tag row.
const RangeBias* findBias(const std::vector<RangeBias>& biases, int anchor_id, int tag_id);

struct Manifest {
  std::string path;  ///< the manifest file itself
  std::string name;
  std::string rawlog;
  std::string ground_truth;
  GroundTruthFormat ground_truth_format = GroundTruthFormat::kNone;
  double gt_max_gap = 1.0;        ///< estimates are scored only between GT samples this close [s]
  double gt_time_offset = 0.0;    ///< added to every reference stamp [s]
  bool reference_heading = true;  ///< the reference's heading is measured (scored as yaw error)
  std::string map;
  std::string range_features;
  std::vector<uwb::Anchor> anchors;  ///< already in the map/GT frame
  /// [anchors] gt_origin_in_anchor_frame (x, y, yaw [rad]), already applied to `anchors`
  std::optional<Eigen::Vector3d> gt_origin_in_anchor_frame;
  std::optional<double> tag_height;
  std::optional<Eigen::Vector2d> lever_arm;
  std::map<int, Eigen::Vector3d> tags;  ///< [tag] tag_<id>: the robot's tags, position on robot
  std::string bias_csv;                 ///< [anchors] bias_csv
  std::vector<RangeBias> biases;        ///< its rows
  std::optional<BoundsSpec> bounds;
  std::optional<double> uwb_sigma;  ///< [uwb] sigma: the methods' default range noise [m]
};

/// Loads and validates a manifest; throws InputError naming the file and line.
/// `data_dir` resolves "${DATA}/" paths (may be empty when none is configured).
Manifest loadManifest(const std::string& path, const std::string& data_dir);

class IdNumbering;  // text_io.hpp

/// Loads anchors from a CSV of "id,x,y,z" rows (a header row, the first with no number among its
/// coordinates, is allowed). With `names`, an id may be a name, numbered by it (after it has seen
/// every integer id of the file); without, it must be an integer. With `z_when_absent`, a file of
/// "id,x,y" rows is read too, every anchor at that height (`*without_z` says so, when given).
std::vector<uwb::Anchor> loadAnchorsCsv(const std::string& path, IdNumbering* names = nullptr,
                                        std::optional<double> z_when_absent = std::nullopt,
                                        bool* without_z = nullptr);
/// The same CSV, with its header.
std::string formatAnchorsCsv(const std::vector<uwb::Anchor>& anchors);

/// What a written manifest says: the files beside it (paths relative to its folder) and the
/// facts of the recording. The one writer of manifests: the simulator and every importer.
struct ManifestDraft {
  std::vector<std::string> comments;  ///< "# " lines at the top (provenance, caveats)
  std::string name;
  std::string rawlog;
  std::string ground_truth;
  GroundTruthFormat ground_truth_format = GroundTruthFormat::kNone;
  std::optional<double> gt_max_gap;
  bool reference_heading = true;
  std::string map;
  std::string range_features;
  std::string anchors_csv;  ///< the anchors file; when empty, `anchors` are written inline
  std::vector<uwb::Anchor> anchors;
  std::optional<double> tag_height;
  std::optional<Eigen::Vector2d> lever_arm;
  std::map<int, Eigen::Vector3d> tags;  ///< [tag] tag_<id> = x y z
  std::string bias_csv;                 ///< [anchors] bias_csv
  /// [bounds]: the recording's LOS range noise, and (motion = odometry) its odometry noise
  /// (xy per metre, theta per radian, theta per metre).
  std::optional<double> bounds_range_sigma;
  std::optional<Eigen::Vector3d> bounds_odometry;
  std::optional<double> uwb_sigma;  ///< [uwb] sigma: the range noise the source states [m]
};

/// The manifest text of `draft`.
std::string formatManifest(const ManifestDraft& draft);

/// Writes `draft` as `dir`/dataset.ini (atomically); returns its path.
std::string writeManifest(const std::string& dir, const ManifestDraft& draft);

/// What an importer wrote, for its one-line summary.
struct ImportSummary {
  std::string manifest;  ///< path of the written manifest
  long ranges = 0;
  long anchors = 0;
  long scans = 0;
  long ground_truth_rows = 0;
  std::map<std::string, long> skipped;  ///< rows left out, by reason (bad stamps, copies, ...)
  std::vector<std::string> notes;       ///< what the importer decided from the data
};

GroundTruthFormat parseGroundTruthFormat(const std::string& text);
const char* toString(GroundTruthFormat f);

}  // namespace uwbloc::data
