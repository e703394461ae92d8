// Importer for CARMEN logs (the Radish "corrected" logs: intel, aces). FLASER lines give a
// 180-degree scan, the SLAM-corrected pose (a reference, not independent ground truth) and the
// odometry pose; ODOM lines give odometry. Gzip-compressed logs are read directly.
#pragma once

#include <string>

#include "uwbloc/dataset/hanyang_import.hpp"

namespace uwbloc::data {

/// Writes carmen.rawlog (scans and odometry), reference.txt ("time x y phi" from the corrected
/// FLASER poses) and dataset.ini. Odometry comes from ODOM lines (FLASER's odometry pose when a
/// log has none). Returns what was written.
ImportSummary importCarmen(const std::string& log_path, const std::string& out_dir);

}  // namespace uwbloc::data
