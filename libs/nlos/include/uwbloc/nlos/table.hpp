// Labelled UWB ranges for NLOS identification and range-error correction, read from the files
// that carry them: the Ghent feature CSVs (Fontaine et al. 2023) and a dataset's
// range_features.csv. Every reader normalises units (metres, first-path index in samples) and
// recomputes the range error as estimated - true from the ranges, so that no file's convention
// leaks into a model.
#pragma once

#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace uwbloc::nlos {

/// Malformed input: the message names the file, and the line and field when there is one.
struct DataError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct EnvironmentCentre;  // model.hpp

/// One range with what the device reported about it. A quantity the file does not carry is NaN.
struct Sample {
  // Channel-impulse-response diagnostics (DW1000 register values).
  double fp_ampl1 = NAN, fp_ampl2 = NAN, fp_ampl3 = NAN;  ///< first-path amplitudes
  double std_noise = NAN;                                 ///< noise standard deviation
  double cir_power = NAN;                                 ///< CIR power C
  double rxpacc = NAN;                                    ///< preamble accumulation count N
  double fp_index = NAN;                                  ///< first-path index [samples]
  double pr = NAN;                                        ///< the Ghent files' Pr column
  // What every device reports.
  double rx_power_dbm = NAN;  ///< received power
  double fp_power_dbm = NAN;  ///< first-path power
  double range = NAN;         ///< estimated range [m]
  /// Predicted distance (odometry / INS / filter prior) minus the measured range [m], when a
  /// motion source produced one (the Sage-Husa paper's second feature).
  double innovation = NAN;
  // Truth: never a feature.
  double true_range = NAN;  ///< [m]
  int label = -1;           ///< 1 NLOS, 0 LOS, -1 unknown
  std::string group;        ///< rows from one spot share it (grouped cross-validation)
  /// The medians of the features over the environment the range came from, subtracted from
  /// them by features() (centreOnEnvironment, RunningCentre); none: the features as measured.
  std::shared_ptr<const EnvironmentCentre> centre;

  /// Estimated minus true range [m]; NaN without a truth.
  double error() const { return range - true_range; }
};

/// The rows of one file, and what the reader did to them.
struct Table {
  std::string source;              ///< the file
  std::vector<Sample> rows;
  std::vector<std::string> notes;  ///< normalisations applied, one line each
  long skipped = 0;                ///< rows without a usable label or range
};

/// A Ghent features file: comma- or semicolon-separated, with or without a trailing separator,
/// a UTF-8 BOM and decimal commas; true range as distance_GT or real_rng; ranges in millimetres
/// or metres (told by their size); fpindex raw (x64) or divided. Groups are the
/// (location_from, location_to) pair when the file has one, else the true range (one spot).
Table readGhent(const std::string& path);

/// A dataset's range_features.csv (t, anchor_id, range, rx_power_dbm, fp_power_dbm, and when
/// the importer had a reference: true_range, error, nlos). Groups are anchor x 10 s of time.
Table readRangeFeatures(const std::string& path);

/// The median of the finite values of `v` (the upper one for an even count), NaN when there is
/// none; `v` is reordered.
double medianOfFinite(std::vector<double>& v);

/// Throws DataError unless `path` is a regular file (a FIFO or a device would never end).
void requireRegularFile(const std::string& path);

/// Either reader, chosen by the file's header.
Table readLabelledRanges(const std::string& path);

}  // namespace uwbloc::nlos
