// A loaded dataset: the event stream, the anchors in the GT frame, and the ground truth.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/localization/events.hpp"
#include "uwbloc/localization/lidar/occupancy_map.hpp"

namespace uwbloc::data {

/// A shift of the reference's stamps at which the ranges fit it (referenceClockShift).
struct ReferenceShift {
  double shift = 0.0;      ///< added to the reference's stamps [s] (as [dataset] gt_time_offset)
  double departure = 0.0;  ///< the ranges' median departure there [m] (rangeReferenceWarning)
  double elsewhere = 0.0;  ///< the median departure at the other shifts tried [m]
};

struct Dataset {
  Manifest manifest;
  std::string name;
  std::vector<loc::Event> events;                ///< time-ordered
  std::vector<uwb::Anchor> anchors;              ///< map/GT frame
  std::vector<TimedPose> ground_truth;           ///< may be empty
  std::shared_ptr<const loc::OccupancyMap> map;  ///< the manifest's map, when it names one
  std::map<std::string, long> counts;            ///< what the reader found
  std::vector<double> step_times;                ///< time of each rawlog step (see rawlog.hpp)
  /// What makes a result from this recording untrustworthy (e.g. collapsed timestamps); the
  /// report prints them, and compare refuses to score such a recording unless told otherwise.
  std::vector<std::string> warnings;
  bool collapsed_time = false;  ///< far fewer distinct timestamps than messages
  /// For a reference that covers under half of the recording, the shift of its stamps at which
  /// the ranges fit it (referenceClockShift), which its warnings give.
  std::optional<ReferenceShift> reference_shift;
  double start_time = 0.0;
  double end_time = 0.0;
  double duration() const { return end_time - start_time; }
  /// Whether the stream has "ranges", "odometry", "scans", or the dataset a "map".
  bool provides(const std::string& need) const;
};

/// Loads the manifest, the rawlog, the ground truth and the optional range-feature side file.
/// The manifest's [tag] keys, when present, override the tag pose recorded in the rawlog, and
/// its bias_csv corrects the ranges (unless `apply_bias` is false: calibration reads raw ranges).
Dataset loadDataset(const std::string& manifest_path, const std::string& data_dir,
                    bool apply_bias = true);

/// When the stream's timestamps have collapsed (far fewer distinct stamps than messages, as when
/// a log was written with too few significant digits), a one-line explanation; nothing otherwise.
/// Rule: at least 50 messages, and fewer distinct readings (kind, stamp, tag, anchor) than a
/// tenth of them: readings that share a stamp by design (one observation's ranges, several tags
/// at once) still differ in what they measure.
std::optional<std::string> collapsedTimeWarning(const std::vector<loc::Event>& events);

/// The shift of the reference's stamps (to add to them, as [dataset] gt_time_offset does) at
/// which the ranges fit it, for a reference whose clock counts from another origin than the
/// recording's (from its start, or in another time zone). Searched 0.1 s apart within 15 s of the
/// shifts that align the two's starts, their ends, and the whole half hour nearest the first,
/// on at most 1000 ranges, each shift scored by the ranges' median departure (as in
/// rangeReferenceWarning) when a quarter of them (50 at least) lie beside the reference; the best
/// refined to 5 ms. Kept when it departs by at most 0.25 m and under half the median departure
/// of the shifts more than 1 s from it (a robot that hardly moves fits every shift alike);
/// nothing otherwise.
std::optional<ReferenceShift> referenceClockShift(const Dataset& ds);

/// When the reference covers under half of the recording's time span (or none of it), a one-line
/// explanation naming both spans, and the shift of its stamps that fits the ranges when
/// loadDataset found one (reference_shift); nothing otherwise (nor when there is no reference).
std::optional<std::string> referenceCoverageWarning(const Dataset& ds);

/// The fraction of the reference's samples within `tolerance` [s] of the recording's span
/// (start_time..end_time): the most coverage any method can reach, since nothing is measured
/// beyond it. 1 without a reference.
double referenceReach(const Dataset& ds, double tolerance = 1.0);

/// When the reference outlasts the recording's measurements so that under 95 % of its samples
/// lie within them (referenceReach), a one-line explanation giving how long it runs before the
/// first and after the last, and the coverage no method can exceed; nothing otherwise. (Under
/// half of the recording covered by the reference is referenceCoverageWarning's.)
std::optional<std::string> referenceBeyondRecordingWarning(const Dataset& ds);

/// When the ranges disagree with the reference, a one-line explanation; nothing otherwise, nor
/// with fewer than 50 ranges beside it. The departure is the median of |each range's error
/// against the distance from the reference pose's tag, less its link's median error| (a
/// consistent bias is no disagreement): about 0.07 m on LOS recordings, 0.2 m under heavy
/// simulated NLOS.
/// - The clocks: the lag of the reference's stamps (within 5 s) at which the ranges agree best;
///   one of 50 ms or more that takes a fifth of the departure away, at least 2 cm, and leaves at
///   most 0.25 m is reported with the [dataset] gt_time_offset that states it (not judged
///   against a reference sampled more than 0.5 s apart).
/// - The frame: over 0.25 m, the multilateration fixes (one tag's ranges within 0.1 s, three
///   anchors or more) are matched to the reference by the rigid motion most of them agree
///   with; one of more than 0.2 m or 2 deg that halves the departure and leaves at most 0.25 m
///   means another frame, reported with the [anchors] gt_origin_in_anchor_frame that says so.
///   Where a lag and a frame both explain it, the one that leaves less.
/// - Otherwise a departure over 1.5 m (beyond any range noise), overall or on one link, is
///   reported with those links and what else can cause it.
std::optional<std::string> rangeReferenceWarning(const Dataset& ds);

/// Range-feature side file: CSV "t,anchor_id,range,rx_power_dbm,fp_power_dbm", one row per
/// range, in the rawlog's order, and when the importer had a reference three more columns,
/// "true_range,error,nlos" (the distance from the reference, estimated - true, and the label
/// that the NLOS trainer reads; empty where the reference does not reach), and last "tag_id".
/// CObservationBeaconRanges has no field for the powers, so the importer writes them here and
/// the loader attaches them to the ranges with the same time, anchor and tag. The columns are
/// read by the header's names (tag_id optional: without it a row fits any tag's range); a file
/// without a header is read by position (5 or 8 columns, no tag). Returns how many ranges
/// received features.
long attachRangeFeatures(const std::string& path, std::vector<loc::Event>& events);

/// What a reference says of one range.
struct RangeLabel {
  double true_range = NAN;  ///< [m]
  int nlos = -1;            ///< 1 NLOS, 0 LOS, -1 unknown
};

/// The side file's text: one row per range (of every tag) that carries its powers; with
/// `truth` (one per event), the three truth columns too; the tag last.
std::string formatRangeFeatures(const std::vector<loc::Event>& events,
                                const std::vector<RangeLabel>* truth = nullptr);

}  // namespace uwbloc::data
