// A small synthetic recording for estimator tests: a robot driving a square loop inside four
// anchors, unsynchronised 10 Hz ranges per anchor with Gaussian noise, exact odometry.
#pragma once

#include <cmath>
#include <random>

#include "uwbloc/dataset/dataset.hpp"

namespace uwbloc::test {

inline data::Dataset makeSquareLoop(uint64_t seed, double sigma = 0.1, double duration = 120.0) {
  data::Dataset ds;
  ds.name = "synthetic_square";
  ds.anchors = {{1, {0, 0, 2.0}}, {2, {8, 0, 2.2}}, {3, {8, 8, 1.8}}, {4, {0, 8, 2.0}}};
  const Eigen::Vector3d tag(0.1, 0.0, 1.0);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  // Square (2,2)-(6,2)-(6,6)-(2,6) at 0.5 m/s, heading along the path.
  auto poseAt = [](double t) {
    const double s = std::fmod(0.5 * t, 16.0);
    const int side = static_cast<int>(s / 4.0);
    const double u = s - 4.0 * side;
    const Eigen::Vector3d corners[4] = {
        {2, 2, 0}, {6, 2, M_PI / 2}, {6, 6, M_PI}, {2, 6, -M_PI / 2}};
    const Eigen::Vector3d c = corners[side];
    return Eigen::Vector3d(c.x() + u * std::cos(c.z()), c.y() + u * std::sin(c.z()), c.z());
  };
  Eigen::Vector3d last = poseAt(0.0);
  const double dt = 0.1;
  for (int k = 0; k * dt <= duration; ++k) {
    const double t = k * dt;
    ds.ground_truth.push_back({t, poseAt(t)});
    if (k > 0) {
      const Eigen::Vector3d now = poseAt(t);
      loc::OdometryIncrement inc;
      inc.t = t;
      inc.delta = loc::relativePose(last, now);
      ds.events.emplace_back(inc);
      last = now;
    }
    for (size_t a = 0; a < ds.anchors.size(); ++a) {
      const double ta = t + 0.02 * static_cast<double>(a);
      const Eigen::Vector3d p = poseAt(ta);
      const double c = std::cos(p.z()), s = std::sin(p.z());
      const Eigen::Vector3d tag_world(p.x() + c * tag.x() - s * tag.y(),
                                      p.y() + s * tag.x() + c * tag.y(), tag.z());
      uwb::Range r;
      r.t = ta;
      r.anchor_id = ds.anchors[a].id;
      r.range = (tag_world - ds.anchors[a].position).norm() + noise(rng);
      r.tag_on_robot = tag;
      ds.events.emplace_back(r);
    }
  }
  ds.start_time = 0.0;
  ds.end_time = duration + 0.06;
  return ds;
}

}  // namespace uwbloc::test
