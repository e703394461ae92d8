// Reader for 2D pose-graph files in the TORO and g2o text forms (MRPT ships both):
//   TORO: VERTEX2 id x y theta;    EDGE2    from to dx dy dtheta I11 I12 I22 I33 I13 I23
//   g2o:  VERTEX_SE2 id x y theta; EDGE_SE2 from to dx dy dtheta I11 I12 I13 I22 I23 I33
// The two store the upper triangle of the information matrix in different orders.
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
    /// Information matrix (x, y, theta), symmetric positive definite.
    Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
  };
  std::vector<Edge> edges;
};

/// Throws InputError naming file and line for malformed rows or unknown record types.
PoseGraphFile readPoseGraph2D(const std::string& path);

}  // namespace uwbloc::data
