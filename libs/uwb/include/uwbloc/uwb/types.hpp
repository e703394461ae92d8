// Plain UWB types shared by every library above this one. Eigen only.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

namespace uwbloc::uwb {

/// A fixed UWB anchor in the map / ground-truth frame.
struct Anchor {
  int id = 0;                                          ///< device id as it appears in the ranges
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< [m], map frame
};

/// One two-way range from the robot's tag to one anchor.
struct Range {
  double t = 0.0;     ///< timestamp [s]
  int anchor_id = 0;  ///< which anchor answered (>= kMobileAnchorBase: another tag)
  int tag_id = 0;     ///< which tag measured
  /// The tag is on the robot (tag_on_robot says where); otherwise it is a mobile node. Readers
  /// set it for tag 0; a manifest's [tag] tag_<id> keys name the robot's other tags.
  bool on_robot = true;
  double range = 0.0;  ///< measured 3D distance [m]
  /// Tag position on the robot (x forward, y left, z up) [m]: lever arm and tag height.
  Eigen::Vector3d tag_on_robot = Eigen::Vector3d::Zero();
  std::optional<double> rx_power_dbm;  ///< received power, when the device reports it
  std::optional<double> fp_power_dbm;  ///< first-path power, when the device reports it
  /// P(NLOS) from a classifier, when one has judged this range (the filters that take it widen
  /// the range's noise by 1 / (1 - p)).
  std::optional<double> nlos_probability;
};

/// Ranges to another tag use anchor id kMobileAnchorBase + that tag's id.
constexpr int kMobileAnchorBase = 1000;

/// Finds an anchor by id; nullptr when unknown.
inline const Anchor* findAnchor(const std::vector<Anchor>& anchors, int id) {
  for (const auto& a : anchors)
    if (a.id == id) return &a;
  return nullptr;
}

}  // namespace uwbloc::uwb
