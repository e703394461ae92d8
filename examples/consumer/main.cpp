// Feeds a uwbloc estimator from the method registry with ranges to four anchors from a robot
// moving along a straight line, and prints the poses it returns.
#include <cmath>
#include <cstdio>

#include "uwbloc/localization/registry.hpp"

int main() {
  using namespace uwbloc;
  loc::EstimatorContext context;
  context.anchors = {{1, {0, 0, 2}}, {2, {10, 0, 2}}, {3, {10, 8, 2}}, {4, {0, 8, 2}}};
  context.seed = 1;
  auto estimator = loc::Registry::builtin().create("uwb-ekf:sigma=0.1", context);
  int poses = 0;
  for (int k = 0; k < 50; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector3d tag(2.0 + 0.5 * t, 4.0, 1.0);  // 0.5 m/s along x, tag 1 m high
    for (const auto& a : context.anchors) {
      uwb::Range r;
      r.t = t;
      r.anchor_id = a.id;
      r.range = (tag - a.position).norm();
      r.tag_on_robot << 0, 0, 1.0;
      if (auto e = estimator->process(r)) {
        if (k % 10 == 0 && a.id == 4)
          std::printf("t=%.1f  x=%.3f  y=%.3f  (truth %.3f %.3f)\n", e->t, e->pose.x(), e->pose.y(),
                      tag.x(), tag.y());
        ++poses;
      }
    }
  }
  // The end of the stream: a method that learns its range model from its first seconds (calib)
  // hands out the estimates it still holds.
  for (const auto& e : estimator->finishAll()) {
    if (poses % 50 == 0)
      std::printf("t=%.1f  x=%.3f  y=%.3f (at the end of the stream)\n", e.t, e.pose.x(),
                  e.pose.y());
    ++poses;
  }
  std::printf("%d poses from %s\n", poses, estimator->name().c_str());
  return poses > 0 ? 0 : 1;
}
