// A recording from plain CSV files, and a dataset back to them.
//
// Files (comma- or blank-separated; '#' comments; an optional header row of column names):
//   ranges     t,anchor_id,range[,tag_id][,rx_power,fp_power]   (3, 4, 5 or 6 columns; with a
//              header the names t/time, anchor_id/anchor, range/distance, tag_id/tag,
//              rx_power[_dbm], fp_power[_dbm] place them)
//   anchors    id,x,y,z
//   odometry   t,dx,dy,dtheta   increments in the robot frame at the start of the motion, or
//              t,x,y,theta      poses (increments taken between consecutive rows), or
//              t,v,omega        velocities (integrated over each row's interval)
//              The kind is named by the header (dx / x / v) or by --odometry-kind; with neither,
//              four columns are poses when the rows' values drift far beyond their row-to-row
//              steps, increments otherwise (the decision is reported).
//   imu        t,gx,gy,gz,ax,ay,az  [rad/s, m/s^2]; the planar part (gz, ax, ay) is kept
//   reference  TUM (t x y z qx qy qz qw), or t,x,y[,theta] (without theta the heading is not
//              scored: reference_heading = false)
//   scans      t,angle_min,angle_increment,r0,r1,...  one scan a row [s, rad, rad, m]; a range
//              <= 0 or not finite is a ray that did not return
// Malformed rows are errors naming the file and line; rows with a bad timestamp or a
// non-finite value are skipped and counted.
#pragma once

#include <map>
#include <optional>
#include <string>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/manifest.hpp"

namespace uwbloc::data {

struct CsvImportRequest {
  std::string ranges, anchors, odometry, imu, reference, scans;
  std::string map;  ///< an occupancy map file (a .gridmap.gz or an image) the manifest names
  std::string odometry_kind = "auto";   ///< auto | increments | poses | velocities
  /// How the odometry's columns are written (odometry_check.hpp): as-written, clockwise (its y and
  /// turn negated), degrees (its turn), mm or cm (its distances); auto: as written, unless
  /// another of these follows the track of the ranges' own fixes where it does not
  /// (betterOdometryReading), which is taken, loudly.
  std::string odometry_convention = "auto";
  std::map<int, Eigen::Vector3d> tags;  ///< tag id -> position on the robot (x y z) [m]
  /// Tags named in the ranges ("T1", "left") -> position on the robot; numbered with them.
  std::map<std::string, Eigen::Vector3d> tag_names;
  std::optional<double> tag_height;     ///< tag 0's height when `tags` is empty [m]
  Eigen::Vector3d scan_pose = Eigen::Vector3d::Zero();  ///< scanner on the robot (x, y, yaw)
  double scan_height = 0.0;                             ///< [m]
  std::optional<double> scan_max_range;  ///< default: the longest range in the file [m]
  std::string name;                      ///< dataset name (default: the output folder's)
  /// The unit of every file's time column: s, ms, us or ns; auto: seconds, unless a file's
  /// median stamp would then fall after the year 3000, where the first of ms, us and ns that
  /// brings it before is taken (the epoch in milliseconds that device logs often carry), loudly.
  std::string time_unit = "auto";
  /// The unit of the ranges: m, cm or mm; auto: metres, unless their median is beyond what the
  /// anchors allow (over 10 times the anchors' largest spacing and over 100 m), where the one of
  /// cm and mm that puts it between a tenth of and 3 times that spacing is taken, loudly (an
  /// error when neither or both do).
  std::string range_unit = "auto";
  /// The unit of the anchors' coordinates: m, cm, mm, in or ft; auto: metres, unless the ranges
  /// cannot be distances to anchors that far apart (range_geometry.hpp: most pairs of ranges from
  /// one tag fall short of their anchors' distance apart) and one of millimetres, centimetres,
  /// inches and feet alone makes them fit, which is taken, loudly. A median range beyond any UWB
  /// link (1 km) among anchors as far apart, both in another unit, is an error naming the two
  /// options.
  std::string anchor_unit = "auto";
};

/// Seconds per unit of `unit` (s, ms, us, ns); throws InputError for another name.
double secondsPerTimeUnit(const std::string& unit);

/// Writes rawlog, anchors.csv, ground_truth.tum, range_features.csv (when the ranges carry
/// powers) and dataset.ini into `out_dir`; ids.csv ("kind,name,id") when anchors or tags are
/// named (a device's "1C8D", "A3") rather than numbered: their numbers in the rest.
ImportSummary importCsv(const CsvImportRequest& request, const std::string& out_dir);

/// Writes `ds` as the CSV files above (ranges.csv, anchors.csv, odometry.csv as increments,
/// imu.csv, reference.tum or reference.csv, scans.csv: each only when the dataset has that
/// stream). Returns the 'uwbloc import csv' arguments that read them back.
std::string exportCsv(const Dataset& ds, const std::string& out_dir);

}  // namespace uwbloc::data
