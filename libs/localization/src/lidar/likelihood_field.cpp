#include "uwbloc/localization/lidar/likelihood_field.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <opencv2/imgproc.hpp>

namespace uwbloc::loc {

namespace {

std::shared_ptr<const LikelihoodGrid> buildGrid(const OccupancyMap& map,
                                                const LikelihoodFieldParams& params) {
  auto g = std::make_shared<LikelihoodGrid>();
  g->nx = map.sizeX();
  g->ny = map.sizeY();
  g->res = map.resolution();
  g->x0 = map.bounds().xmin;
  g->y0 = map.bounds().ymin;
  // Exact Euclidean distance, in cells, from each cell to the nearest occupied one (OpenCV's
  // distanceTransform with the precise mask: Felzenszwalb and Huttenlocher's algorithm). Rows
  // are cy, columns cx; a zero pixel is an occupied cell.
  cv::Mat free_cells(g->ny, g->nx, CV_8UC1);
  for (int cy = 0; cy < g->ny; ++cy)
    for (int cx = 0; cx < g->nx; ++cx)
      free_cells.at<uint8_t>(cy, cx) = map.freeProbability(cx, cy) < 0.5f ? 0 : 255;
  cv::Mat cells;
  cv::distanceTransform(free_cells, cells, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  const size_t n = static_cast<size_t>(g->nx) * static_cast<size_t>(g->ny);
  g->dist.resize(n);
  g->log_p.resize(n);
  const double norm = 1.0 / (std::sqrt(2.0 * M_PI) * params.sigma_hit);
  const double uniform = params.z_rand / params.max_range;
  auto logp = [&](double dist) {
    return std::log(params.z_hit * norm *
                        std::exp(-0.5 * dist * dist / (params.sigma_hit * params.sigma_hit)) +
                    uniform);
  };
  for (int cy = 0; cy < g->ny; ++cy)
    for (int cx = 0; cx < g->nx; ++cx) {
      const size_t i = static_cast<size_t>(cy) * static_cast<size_t>(g->nx) + cx;
      g->dist[i] = static_cast<float>(
          std::min<double>(static_cast<double>(cells.at<float>(cy, cx)) * g->res, params.max_dist));
      g->log_p[i] = static_cast<float>(logp(g->dist[i]));
    }
  g->log_p_far = logp(params.max_dist);
  return g;
}

// The tables built so far, each kept while its map lives. An entry matches the same map object
// (the same shared owner, still alive) and the same model values.
struct GridCache {
  struct Entry {
    std::weak_ptr<const OccupancyMap> map;
    std::array<double, 5> model;
    std::shared_ptr<const LikelihoodGrid> grid;
  };
  std::mutex mutex;
  std::vector<Entry> entries;
};

std::shared_ptr<const LikelihoodGrid> sharedGrid(const std::shared_ptr<const OccupancyMap>& map,
                                                 const LikelihoodFieldParams& p) {
  static GridCache cache;
  const std::array<double, 5> model{p.sigma_hit, p.z_hit, p.z_rand, p.max_dist, p.max_range};
  const std::lock_guard<std::mutex> lock(cache.mutex);
  auto& entries = cache.entries;
  entries.erase(std::remove_if(entries.begin(), entries.end(),
                               [](const GridCache::Entry& e) { return e.map.expired(); }),
                entries.end());
  for (const auto& e : entries)
    if (!e.map.owner_before(map) && !map.owner_before(e.map) && e.model == model) return e.grid;
  // Built under the lock: a concurrent run asking for the same tables waits for them.
  entries.push_back({map, model, buildGrid(*map, p)});
  return entries.back().grid;
}

}  // namespace

LikelihoodField::LikelihoodField(const OccupancyMap& map, const LikelihoodFieldParams& params)
    : params_(params), grid_(buildGrid(map, params)) {}

LikelihoodField::LikelihoodField(const std::shared_ptr<const OccupancyMap>& map,
                                 const LikelihoodFieldParams& params)
    : params_(params), grid_(sharedGrid(map, params)) {}

double LikelihoodField::distance(double x, double y) const {
  const LikelihoodGrid& g = *grid_;
  const int cx = static_cast<int>(std::floor((x - g.x0) / g.res));
  const int cy = static_cast<int>(std::floor((y - g.y0) / g.res));
  if (cx < 0 || cy < 0 || cx >= g.nx || cy >= g.ny) return params_.max_dist;
  return g.dist[static_cast<size_t>(cy) * g.nx + cx];
}

void LikelihoodField::setScan(const LaserScan& scan) {
  ex_.clear();
  ey_.clear();
  // Max-range readings are no returns.
  const double max_range = std::min(params_.max_range, scan.max_range - 1e-3);
  forEachScanEndpoint(scan, static_cast<size_t>(std::max(1, params_.decimation)), params_.min_range,
                      max_range, [&](size_t, const Eigen::Vector2d& p) {
                        ex_.push_back(p.x());
                        ey_.push_back(p.y());
                      });
}

double LikelihoodField::logLikelihood(double x, double y, double theta) const {
  const LikelihoodGrid& g = *grid_;
  const double c = std::cos(theta), s = std::sin(theta);
  double sum = 0.0;
  for (size_t i = 0; i < ex_.size(); ++i) {
    const double wx = x + c * ex_[i] - s * ey_[i];
    const double wy = y + s * ex_[i] + c * ey_[i];
    const int cx = static_cast<int>(std::floor((wx - g.x0) / g.res));
    const int cy = static_cast<int>(std::floor((wy - g.y0) / g.res));
    sum += (cx < 0 || cy < 0 || cx >= g.nx || cy >= g.ny)
               ? g.log_p_far
               : static_cast<double>(g.log_p[static_cast<size_t>(cy) * g.nx + cx]);
  }
  return sum;
}

double LikelihoodField::fitFraction(double x, double y, double theta, double tolerance) const {
  if (ex_.empty()) return 0.0;
  const double c = std::cos(theta), s = std::sin(theta);
  size_t near = 0;
  for (size_t i = 0; i < ex_.size(); ++i)
    near += distance(x + c * ex_[i] - s * ey_[i], y + s * ex_[i] + c * ey_[i]) <= tolerance;
  return static_cast<double>(near) / static_cast<double>(ex_.size());
}

}  // namespace uwbloc::loc
