// Range calibration from recordings with a reference: per-anchor or per-link (anchor, tag) range
// bias, optional scale, range noise, and the positions of anchors marked unknown.
//
// Model of one range from tag k to anchor a, the tag at p_k = tag position of the reference
// pose at the range's time (lever arm and height included):
//
//   measured = (1 + s_g) ||anchor_a - p_k|| + b_g + noise,     g = a (per anchor) or (a, k)
//
// The anchors' z stays as given (a planar robot hardly observes it). The fit is a Ceres problem
// with a Huber loss of 2 sigma, sigma first taken as 1.4826 MAD of the residuals to the median
// bias: NLOS ranges and outliers weigh little. Each group's noise is the 1.4826 MAD of its
// residuals after the fit.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"

namespace uwbloc::eval {

struct CalibrationOptions {
  bool per_link = true;           ///< one bias per (anchor, tag); false: one per anchor
  bool scale = false;             ///< also fit a scale per group
  std::vector<int> free_anchors;  ///< anchors whose x, y are unknown
};

struct CalibrationResult {
  std::vector<uwb::Anchor> anchors;  ///< the anchors, free ones estimated
  std::vector<data::RangeBias> biases;
  std::map<int, double> anchor_moved;  ///< free anchor -> distance moved in x, y [m]
  long samples = 0;                    ///< ranges with a reference pose
  long skipped = 0;                    ///< ranges without one (outside or in a gap)
  double sigma = 0.0;                  ///< 1.4826 MAD of all residuals after the fit [m]
  std::vector<std::string> notes;      ///< what the fit saw and could not do
};

/// Fits the model to every range of `datasets` that has a reference pose. The datasets must
/// share their anchor ids (the first one's positions are the start). Throws InputError when no
/// range has a reference, or an anchor to free is unknown.
CalibrationResult calibrateRanges(const std::vector<const data::Dataset*>& datasets,
                                  const CalibrationOptions& options);

/// The result as a table: one row per group (bias, scale, sigma, samples), then the free anchors.
std::string formatCalibration(const CalibrationResult& result);

/// Static ranging at known distances (the Hanyang static layout: <dir>/<condition>/<group>/
/// <D>m.csv, e.g. LOS/height_100.0cm/10m.csv, each file the device's ranges at true distance D):
/// per condition and group, the range error (device - true) fitted as offset + scale * D (least
/// squares on each file's median error, so a file's outliers do not pull it), and the noise
/// 1.4826 MAD of every range's residual to the fit.
struct DistanceErrorFit {
  std::string condition, group;  ///< e.g. "LOS", "height_100.0cm"
  int files = 0;                 ///< files with ranges
  long ranges = 0;
  double offset = 0.0, scale = 0.0, sigma = 0.0;  ///< [m], [-], [m]
  double min_distance = 0.0, max_distance = 0.0;  ///< [m]
};
struct StaticRangingReport {
  std::vector<DistanceErrorFit> fits;
  std::vector<std::string> problems;  ///< files that were empty or corrupt, or rows skipped
};
/// Throws InputError when `dir` holds no such file.
StaticRangingReport fitStaticRanging(const std::string& dir);
std::string formatStaticRanging(const StaticRangingReport& report);

}  // namespace uwbloc::eval
