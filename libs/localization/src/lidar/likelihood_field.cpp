#include "uwbloc/localization/lidar/likelihood_field.hpp"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace uwbloc::loc {

LikelihoodField::LikelihoodField(const OccupancyMap& map, const LikelihoodFieldParams& params)
    : params_(params) {
  nx_ = map.sizeX();
  ny_ = map.sizeY();
  res_ = map.resolution();
  x0_ = map.bounds().xmin;
  y0_ = map.bounds().ymin;
  // Exact Euclidean distance, in cells, from each cell to the nearest occupied one (OpenCV's
  // distanceTransform with the precise mask: Felzenszwalb and Huttenlocher's algorithm). Rows
  // are cy, columns cx; a zero pixel is an occupied cell.
  cv::Mat free_cells(ny_, nx_, CV_8UC1);
  for (int cy = 0; cy < ny_; ++cy)
    for (int cx = 0; cx < nx_; ++cx)
      free_cells.at<uint8_t>(cy, cx) = map.freeProbability(cx, cy) < 0.5f ? 0 : 255;
  cv::Mat cells;
  cv::distanceTransform(free_cells, cells, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
  std::vector<float> d(static_cast<size_t>(nx_) * ny_);
  for (int cy = 0; cy < ny_; ++cy)
    for (int cx = 0; cx < nx_; ++cx)
      d[static_cast<size_t>(cy) * nx_ + cx] = cells.at<float>(cy, cx);
  dist_.resize(d.size());
  log_p_.resize(d.size());
  const double norm = 1.0 / (std::sqrt(2.0 * M_PI) * params_.sigma_hit);
  const double uniform = params_.z_rand / params_.max_range;
  auto logp = [&](double dist) {
    return std::log(params_.z_hit * norm *
                        std::exp(-0.5 * dist * dist / (params_.sigma_hit * params_.sigma_hit)) +
                    uniform);
  };
  for (size_t i = 0; i < d.size(); ++i) {
    dist_[i] = static_cast<float>(std::min<double>(d[i] * res_, params_.max_dist));
    log_p_[i] = static_cast<float>(logp(dist_[i]));
  }
  log_p_far_ = logp(params_.max_dist);
}

double LikelihoodField::distance(double x, double y) const {
  const int cx = static_cast<int>(std::floor((x - x0_) / res_));
  const int cy = static_cast<int>(std::floor((y - y0_) / res_));
  if (cx < 0 || cy < 0 || cx >= nx_ || cy >= ny_) return params_.max_dist;
  return dist_[static_cast<size_t>(cy) * nx_ + cx];
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
  const double c = std::cos(theta), s = std::sin(theta);
  double sum = 0.0;
  for (size_t i = 0; i < ex_.size(); ++i) {
    const double wx = x + c * ex_[i] - s * ey_[i];
    const double wy = y + s * ex_[i] + c * ey_[i];
    const int cx = static_cast<int>(std::floor((wx - x0_) / res_));
    const int cy = static_cast<int>(std::floor((wy - y0_) / res_));
    sum += (cx < 0 || cy < 0 || cx >= nx_ || cy >= ny_)
               ? log_p_far_
               : static_cast<double>(log_p_[static_cast<size_t>(cy) * nx_ + cx]);
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
