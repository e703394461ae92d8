#include "uwbloc/dataset/pose_graph_file.hpp"

#include <Eigen/Cholesky>
#include <cmath>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace uwbloc::data {

PoseGraphFile readPoseGraph2D(const std::string& path) {
  PoseGraphFile g;
  forEachRow(path, [&](int line, const std::vector<std::string>& f) {
    auto num = [&](size_t i, const char* what) {
      if (i >= f.size()) throwInputError(path, line, std::string("missing field '") + what + "'");
      return parseNumber(f[i], path, line, what);
    };
    auto id = [&](size_t i, const char* what) {
      if (i >= f.size()) throwInputError(path, line, std::string("missing field '") + what + "'");
      return parseId(f[i], path, line, what);
    };
    if (f[0] == "VERTEX2" || f[0] == "VERTEX_SE2") {
      g.vertices[id(1, "id")] = Eigen::Vector3d(num(2, "x"), num(3, "y"), num(4, "theta"));
    } else if (f[0] == "EDGE2" || f[0] == "EDGE_SE2") {
      PoseGraphFile::Edge e;
      e.from = id(1, "from");
      e.to = id(2, "to");
      e.delta << num(3, "dx"), num(4, "dy"), num(5, "dtheta");
      // The upper triangle, in each format's own order (see the header).
      const bool toro = f[0] == "EDGE2";
      const double i11 = num(6, "I11"), i12 = num(7, "I12");
      const double i22 = num(toro ? 8 : 9, "I22"), i33 = num(toro ? 9 : 11, "I33");
      const double i13 = num(toro ? 10 : 8, "I13"), i23 = num(toro ? 11 : 10, "I23");
      e.information << i11, i12, i13, i12, i22, i23, i13, i23, i33;
      if (e.information.llt().info() != Eigen::Success)
        throwInputError(path, line, "information matrix is not positive definite");
      g.edges.push_back(e);
    } else {
      throwInputError(path, line, "unknown record '" + f[0] + "'");
    }
  });
  if (g.vertices.empty()) throwInputError(path, 0, "no vertices");
  return g;
}

}  // namespace uwbloc::data
