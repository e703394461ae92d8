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

}  // namespace uwbloc::eval
