// Importer for one dynamic run of the Hanyang outdoor UWB dataset.
//
// Input folder: one CSV per anchor (A3.csv, A5.csv, ...) with rows
//   %time,field.stamp,field.id,field.x,field.y,field.z,field.distanceFromTag,field.rssi,
//   field.rssi_fp
// (ns timestamps; the anchor's position repeated on every row), and trajectory.csv with
//   timestamp,x,y,z,heading_degrees (RTK reference in the anchor frame).
//
// Output folder: uwb.rawlog (CObservationBeaconRanges, time = field.stamp), anchors.csv,
// ground_truth.tum, range_features.csv (received and first-path power per range; the format is
// in dataset.hpp) and dataset.ini, the manifest tying them together.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "uwbloc/dataset/manifest.hpp"

namespace uwbloc::data {

struct HanyangImportParams {
  double tag_height = 1.0;  ///< tag height above the anchors' z datum [m]
};

/// One two-way-ranging exchange of a Hanyang static file (static/{LOS,NLOS}/height_*/Nm.csv):
/// raw DW1000 timestamps (stored as wrapped signed 32-bit numbers) and the device's distance.
struct TwrExchange {
  int64_t poll_tx = 0, poll_rx = 0, resp_tx = 0, resp_rx = 0;  ///< DW1000 ticks
  double device_distance = 0.0;                                ///< the file's Distance [m]
};

struct TwrFile {
  std::vector<TwrExchange> exchanges;
  long incomplete_rows = 0;  ///< rows with an empty or non-numeric timestamp (skipped, counted)
};

/// Reads the raw timestamps and the device distance of a static file. Throws InputError naming
/// the file when a needed column is missing.
TwrFile readHanyangStatic(const std::string& path);

ImportSummary importHanyang(const std::string& run_dir, const std::string& out_dir,
                            const HanyangImportParams& params = {});

}  // namespace uwbloc::data
