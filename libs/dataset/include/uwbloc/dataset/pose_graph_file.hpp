// Reader for 2D pose-graph files in the TORO / g2o "VERTEX2" / "EDGE2" text form (as MRPT ships
// them): VERTEX2 id x y theta; EDGE2 from to dx dy dtheta I11 I12 I22 I33 I13 I23.
#pragma once

#include <Eigen/Core>
#include <map>
#include <string>
#include <vector>

namespace uwbloc::data {

struct PoseGraphFile {
  std::map<int, Eigen::Vector3d> vertices;
  struct Edge {
    int from = 0, to = 0;
    Eigen::Vector3d delta = Eigen::Vector3d::Zero();
    Eigen::Vector3d sigma = Eigen::Vector3d::Ones();  ///< 1 / sqrt of the information diagonal
  };
  std::vector<Edge> edges;
};

/// Throws InputError naming file and line for malformed rows or unknown record types.
PoseGraphFile readPoseGraph2D(const std::string& path);

}  // namespace uwbloc::data
