// Likelihood-field model of a 2D scan on an occupancy grid (Thrun et al., ch. 6.4; the model
// behind MRPT's COccupancyGridMap2D::lmLikelihoodField_Thrun): each ray endpoint scores
//   p = z_hit N(d; 0, sigma_hit) + z_rand / max_range,
// d the distance from the endpoint to the nearest occupied cell, precomputed once for the whole
// grid, so a particle's score is a few table look-ups per ray.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "uwbloc/localization/events.hpp"
#include "uwbloc/localization/lidar/occupancy_map.hpp"

namespace uwbloc::loc {

struct LikelihoodFieldParams {
  double sigma_hit = 0.2;   ///< endpoint noise [m]
  double z_hit = 0.9;       ///< weight of the Gaussian part
  double z_rand = 0.1;      ///< weight of the uniform part
  double max_dist = 0.2;    ///< distances are capped here [m] (MRPT: LF_maxCorrsDistance)
  int decimation = 20;      ///< use every n-th ray
  double max_range = 30.0;  ///< rays at or beyond this are ignored [m]
  double min_range = 0.05;  ///< rays below this are ignored [m]
};

/// The per-cell tables of a likelihood field. They depend only on the map and on the model's
/// sigma_hit, z_hit, z_rand, max_dist and max_range, and are read-only once built.
struct LikelihoodGrid {
  double x0 = 0, y0 = 0, res = 0.05;
  int nx = 0, ny = 0;
  std::vector<float> log_p;  ///< per cell: log(z_hit N(d) + z_rand / max_range)
  std::vector<float> dist;   ///< per cell: distance to the nearest occupied cell [m]
  double log_p_far = 0.0;    ///< the same beyond max_dist and outside the map
};

class LikelihoodField {
 public:
  /// Builds the tables for this field alone.
  LikelihoodField(const OccupancyMap& map, const LikelihoodFieldParams& params);
  /// Shares the tables with every other field built on the same map with the same model: the
  /// tables are built once per (map, model) while the map lives, and every run of a `compare`
  /// on that map, serial or concurrent, reads the same copy. The map must not change after.
  LikelihoodField(const std::shared_ptr<const OccupancyMap>& map,
                  const LikelihoodFieldParams& params);

  /// Distance [m] from (x, y) to the nearest occupied cell (max_dist outside the map).
  double distance(double x, double y) const;
  /// Stores the scan's usable ray endpoints in the robot frame (no allocation after the first).
  void setScan(const LaserScan& scan);
  size_t rays() const { return ex_.size(); }
  /// Log-likelihood of the stored scan from robot pose (x, y, theta).
  double logLikelihood(double x, double y, double theta) const;
  /// Fraction of the stored scan's endpoints within `tolerance` of an obstacle, seen from
  /// (x, y, theta): how well the scan fits the map there (0 without endpoints).
  double fitFraction(double x, double y, double theta, double tolerance) const;
  /// True when both read the same tables (built once for their map and model).
  bool sharesTables(const LikelihoodField& other) const { return grid_ == other.grid_; }

 private:
  LikelihoodFieldParams params_;
  std::shared_ptr<const LikelihoodGrid> grid_;
  std::vector<double> ex_, ey_;  ///< current scan endpoints in the robot frame
};

}  // namespace uwbloc::loc
