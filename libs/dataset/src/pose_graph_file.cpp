#include "uwbloc/dataset/pose_graph_file.hpp"

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
    if (f[0] == "VERTEX2" || f[0] == "VERTEX_SE2") {
      g.vertices[static_cast<int>(num(1, "id"))] =
          Eigen::Vector3d(num(2, "x"), num(3, "y"), num(4, "theta"));
    } else if (f[0] == "EDGE2" || f[0] == "EDGE_SE2") {
      PoseGraphFile::Edge e;
      e.from = static_cast<int>(num(1, "from"));
      e.to = static_cast<int>(num(2, "to"));
      e.delta << num(3, "dx"), num(4, "dy"), num(5, "dtheta");
      // EDGE2 stores I11 I12 I22 I33 I13 I23; the diagonal whitens each component (the
      // off-diagonal terms are dropped).
      const double i11 = num(6, "I11"), i22 = num(8, "I22"), i33 = num(9, "I33");
      if (!(i11 > 0 && i22 > 0 && i33 > 0))
        throwInputError(path, line, "information must be positive");
      e.sigma << 1 / std::sqrt(i11), 1 / std::sqrt(i22), 1 / std::sqrt(i33);
      g.edges.push_back(e);
    } else {
      throwInputError(path, line, "unknown record '" + f[0] + "'");
    }
  });
  if (g.vertices.empty()) throwInputError(path, 0, "no vertices");
  return g;
}

}  // namespace uwbloc::data
