// Importer for the LIAS-CUHKSZ planar UWB dataset: three tags on a rigid trolley, eight anchors.
//
// Input: one UWB file, "time,a0-t0,a0-t1,a0-t2,a1-t0,...,a7-t2" (no header; time as
// "YYYY-MM-DD H:MM:SS.mmm"; 24 ranges a row, tag index fastest), either
//  - a dynamic run (Dynamic/UWB_dynamic_exp_<speed>.csv) with its motion-capture file beside it
//    (motion_capture_dynamic_exp_<speed>.csv: "time,x,y,z,qw,qx,qy,qz" of the body centroid), or
//  - a static run (Static/UWB_static_exp_<month>_<day>_pos<k>_deg_<d>.csv) whose pose is in the
//    static README's table for that day (pose k, the row whose yaw is nearest d degrees).
// The anchor and tag coordinates come from the dataset's own READMEs (Planar_Dataset/Dynamic/
// README.md, Planar_Dataset/Static/README.md), found above the UWB file.
//
// What the importer decides from the data, and reports:
//  - how the motion capture's orientation maps to the robot's heading and to the tags' lever
//    arms (the body frame may be flipped), and the clock offset between motion capture and UWB:
//    the candidates are scored by the median range residual against the reference;
//  - the tags' height: the motion capture's median z (a static run takes it from the dynamic
//    run's motion capture beside it, or from --tag-height);
//  - a static run's heading: the README's yaw comes from the same motion capture, so the
//    convention found on the dynamic run beside it (heading sign, lever-arm mirror, heading
//    offset) applies to it too (or --yaw-offset). On the shared copy the offset is +6 degrees:
//    taken as the README's yaw, the static runs' three-tag headings were 4-11 degrees off.
//
// Output: uwb.rawlog (tag k's ranges as sensor UWB / UWB_TAG<k>), anchors.csv,
// ground_truth.tum (heading included) and dataset.ini listing the three tags.
#pragma once

#include <optional>
#include <string>

#include "uwbloc/dataset/manifest.hpp"

namespace uwbloc::data {

struct LiasImportParams {
  std::optional<double> tag_height;  ///< tags' height above the anchors' z datum [m]
  std::string bias_csv;              ///< per-link bias table to copy and name in the manifest
  std::string readme;                ///< the README with the coordinates (default: found)
  /// Static runs: robot heading = the README's yaw + this [deg]; default: the offset (and
  /// heading sign, lever-arm mirror) found on the dynamic run beside the Static folder.
  std::optional<double> yaw_offset_deg;
};

/// Seconds since 1970-01-01 of "YYYY-MM-DD H:MM:SS[.fff]" (read as UTC); nothing when the text
/// is not such a time.
std::optional<double> parseDateTime(const std::string& text);

ImportSummary importLias(const std::string& uwb_file, const std::string& out_dir,
                         const LiasImportParams& params = {});

}  // namespace uwbloc::data
