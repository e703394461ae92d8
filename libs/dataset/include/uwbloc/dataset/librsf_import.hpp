// Importer for libRSF's UWB datasets (text: one measurement a line, its type first), as its
// datasets' readme files define them:
//   range2    t range variance anchor_x anchor_y anchor_id [snr]      [s, m, m^2, m, m, -]
//   odom2diff t v_right v_left v_y wheel_base ... var_right var_left var_y   [m/s, m]
//   point2    t x y [covariance 2x2]     reference position (also read: gt2 t x y)
// The range's fourth field is a variance (the readme: "range covariance [m]^2"); its median
// square root becomes the manifest's [uwb] sigma. Anchors are planar (z = 0) and taken from the
// range lines (an anchor id seen at two places is an error naming the line). Odometry: speed
// (v_r + v_l) / 2, yaw rate (v_r - v_l) / wheel_base and v_y, each line's velocities integrated
// over the interval that ends at its time. Lines of other types are skipped and counted.
// The reference is read from the same file and, when `reference` is empty, from the file whose
// name has _GT in place of _Input; it has no heading (reference_heading = false).
#pragma once

#include <string>

#include "uwbloc/dataset/manifest.hpp"

namespace uwbloc::data {

ImportSummary importLibrsf(const std::string& file, const std::string& out_dir,
                           const std::string& reference = "");

}  // namespace uwbloc::data
