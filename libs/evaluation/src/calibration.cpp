#include "uwbloc/evaluation/calibration.hpp"

#include <ceres/ceres.h>

#include <Eigen/QR>
#include <filesystem>
#include <regex>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::eval {

namespace {

struct Sample {
  int group = 0;          ///< index into the groups
  int anchor = 0;         ///< index into the anchors
  Eigen::Vector3d tag;    ///< tag position from the reference [m]
  double measured = 0.0;  ///< [m]
};

// measured - ((1 + s) |anchor - tag| + b), anchor x, y free, z fixed.
struct RangeResidual {
  Eigen::Vector3d tag;
  double anchor_z, measured;
  template <class T>
  bool operator()(const T* anchor_xy, const T* bias, const T* scale, T* r) const {
    const T dx = anchor_xy[0] - T(tag.x()), dy = anchor_xy[1] - T(tag.y());
    const T dz = T(anchor_z - tag.z());
    r[0] = T(measured) - ((T(1.0) + scale[0]) * ceres::sqrt(dx * dx + dy * dy + dz * dz) + bias[0]);
    return true;
  }
};

double mad(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const double m = quantile(v, 0.5);
  for (auto& x : v) x = std::abs(x - m);
  return 1.4826 * quantile(v, 0.5);
}

}  // namespace

CalibrationResult calibrateRanges(const std::vector<const data::Dataset*>& datasets,
                                  const CalibrationOptions& options) {
  if (datasets.empty()) throw data::InputError("calibrate: no recording given");
  CalibrationResult out;
  out.anchors = datasets.front()->anchors;
  for (const auto* ds : datasets)
    for (const auto& a : ds->anchors) {
      const uwb::Anchor* first = uwb::findAnchor(out.anchors, a.id);
      if (!first) {
        out.anchors.push_back(a);
      } else if ((first->position - a.position).norm() > 1e-3) {
        out.notes.push_back(ds->manifest.path + ": anchor " + std::to_string(a.id) +
                            " is not where the first recording has it; the first position is "
                            "the start");
      }
    }
  const std::set<int> free(options.free_anchors.begin(), options.free_anchors.end());
  for (int id : free)
    if (!uwb::findAnchor(out.anchors, id))
      throw data::InputError("calibrate: anchor " + std::to_string(id) +
                             " to estimate is in no recording");

  // Groups: (anchor, tag) per link, (anchor, -1) per anchor.
  std::map<std::pair<int, int>, int> group_of;
  std::vector<std::pair<int, int>> groups;
  std::vector<Sample> samples;
  for (const auto* ds : datasets) {
    if (ds->ground_truth.empty())
      throw data::InputError(ds->manifest.path + ": calibrate needs a reference (ground_truth)");
    for (const auto& e : ds->events) {
      const auto* r = std::get_if<uwb::Range>(&e);
      if (!r || !r->on_robot || !std::isfinite(r->range) || r->range <= 0.0) continue;
      const auto it = std::find_if(out.anchors.begin(), out.anchors.end(),
                                   [&](const uwb::Anchor& a) { return a.id == r->anchor_id; });
      if (it == out.anchors.end()) continue;
      const auto pose = interpolateGroundTruth(ds->ground_truth, r->t, ds->manifest.gt_max_gap);
      if (!pose) {
        ++out.skipped;
        continue;
      }
      const std::pair<int, int> key{r->anchor_id, options.per_link ? r->tag_id : -1};
      const auto [g, inserted] = group_of.try_emplace(key, static_cast<int>(groups.size()));
      if (inserted) groups.push_back(key);
      samples.push_back({g->second, static_cast<int>(it - out.anchors.begin()),
                         uwb::tagPosition(*pose, r->tag_on_robot), r->range});
    }
  }
  if (samples.empty())
    throw data::InputError("calibrate: no range has a reference pose at its time");
  out.samples = static_cast<long>(samples.size());

  // Start: each group's bias is the median residual; the loss scale from the residuals' MAD.
  auto residual = [&](const Sample& s, const std::vector<Eigen::Vector3d>& anchors,
                      const std::vector<double>& bias, const std::vector<double>& scale) {
    return s.measured - ((1.0 + scale[static_cast<size_t>(s.group)]) *
                             (anchors[static_cast<size_t>(s.anchor)] - s.tag).norm() +
                         bias[static_cast<size_t>(s.group)]);
  };
  std::vector<Eigen::Vector3d> anchors;
  for (const auto& a : out.anchors) anchors.push_back(a.position);
  std::vector<double> bias(groups.size(), 0.0), scale(groups.size(), 0.0);
  std::vector<std::vector<double>> per_group(groups.size());
  for (const auto& s : samples)
    per_group[static_cast<size_t>(s.group)].push_back(residual(s, anchors, bias, scale));
  std::vector<double> centred;
  for (size_t g = 0; g < groups.size(); ++g) {
    bias[g] = quantile(per_group[g], 0.5);
    for (double v : per_group[g]) centred.push_back(v - bias[g]);
  }
  const double sigma0 = std::max(mad(centred), 0.005);

  ceres::Problem problem;
  std::vector<Eigen::Vector2d> xy;
  for (const auto& a : anchors) xy.emplace_back(a.head<2>());
  for (const auto& s : samples) {
    const auto g = static_cast<size_t>(s.group);
    const auto a = static_cast<size_t>(s.anchor);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<RangeResidual, 1, 2, 1, 1>(
                                 new RangeResidual{s.tag, anchors[a].z(), s.measured}),
                             new ceres::HuberLoss(2.0 * sigma0), xy[a].data(), &bias[g], &scale[g]);
  }
  for (size_t a = 0; a < xy.size(); ++a)
    if (problem.HasParameterBlock(xy[a].data()) && !free.count(out.anchors[a].id))
      problem.SetParameterBlockConstant(xy[a].data());
  if (!options.scale)
    for (auto& s : scale) problem.SetParameterBlockConstant(&s);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = 100;
  so.num_threads = 2;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (!summary.IsSolutionUsable())
    throw std::runtime_error("calibrate: the fit failed: " + summary.BriefReport());

  for (size_t a = 0; a < xy.size(); ++a) {
    anchors[a].head<2>() = xy[a];
    if (free.count(out.anchors[a].id))
      out.anchor_moved[out.anchors[a].id] = (xy[a] - out.anchors[a].position.head<2>()).norm();
    out.anchors[a].position = anchors[a];
  }
  for (auto& v : per_group) v.clear();
  centred.clear();
  for (const auto& s : samples) {
    const double r = residual(s, anchors, bias, scale);
    per_group[static_cast<size_t>(s.group)].push_back(r);
    centred.push_back(r);
  }
  out.sigma = mad(centred);
  for (size_t g = 0; g < groups.size(); ++g) {
    data::RangeBias b;
    b.anchor_id = groups[g].first;
    if (groups[g].second >= 0) b.tag_id = groups[g].second;
    b.bias = bias[g];
    b.scale = scale[g];
    b.sigma = mad(per_group[g]);
    b.samples = static_cast<long>(per_group[g].size());
    out.biases.push_back(b);
    if (b.samples < 30)
      out.notes.push_back("anchor " + std::to_string(b.anchor_id) +
                          (b.tag_id ? ", tag " + std::to_string(*b.tag_id) : "") + ": only " +
                          std::to_string(b.samples) + " ranges; its bias is uncertain");
  }
  std::sort(out.biases.begin(), out.biases.end(), [](const auto& x, const auto& y) {
    return std::pair(x.anchor_id, x.tag_id.value_or(-1)) <
           std::pair(y.anchor_id, y.tag_id.value_or(-1));
  });
  if (!free.empty() && !options.scale)
    out.notes.push_back("anchor z kept as given (a planar robot hardly observes it)");
  return out;
}

StaticRangingReport fitStaticRanging(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw data::InputError(dir + ": folder not found");
  static const std::regex file_name(R"(([0-9]+(\.[0-9]+)?)m\.csv)");
  std::map<std::pair<std::string, std::string>, std::vector<std::pair<double, std::string>>> files;
  for (const auto& e : fs::recursive_directory_iterator(dir, ec)) {
    std::smatch m;
    const std::string name = e.path().filename().string();
    if (!e.is_regular_file() || !std::regex_match(name, m, file_name)) continue;
    const fs::path group = e.path().parent_path();
    files[{group.parent_path().filename().string(), group.filename().string()}].emplace_back(
        std::stod(m[1].str()), e.path().string());
  }
  if (files.empty()) throw data::InputError(dir + ": no <distance>m.csv file below it");
  StaticRangingReport report;
  for (auto& [key, list] : files) {
    std::sort(list.begin(), list.end());
    std::vector<double> d, med;
    std::vector<std::pair<double, double>> all;  // (true distance, error)
    DistanceErrorFit fit;
    fit.condition = key.first;
    fit.group = key.second;
    long incomplete = 0, files_with_incomplete = 0;
    for (const auto& [distance, path] : list) {
      data::TwrFile twr;
      try {
        twr = data::readHanyangStatic(path);
      } catch (const data::InputError& e) {
        report.problems.push_back(std::string(e.what()) + " (file skipped)");
        continue;
      }
      if (twr.incomplete_rows > 0) {
        incomplete += twr.incomplete_rows;
        ++files_with_incomplete;
      }
      std::vector<double> err;
      for (const auto& x : twr.exchanges)
        if (std::isfinite(x.device_distance) && x.device_distance > 0.0)
          err.push_back(x.device_distance - distance);
      if (err.empty()) {
        report.problems.push_back(path + ": no range (empty file)");
        continue;
      }
      d.push_back(distance);
      med.push_back(quantile(err, 0.5));
      for (double v : err) all.emplace_back(distance, v);
      ++fit.files;
      fit.ranges += static_cast<long>(err.size());
    }
    if (incomplete > 0)
      report.problems.push_back(key.first + "/" + key.second + ": " + std::to_string(incomplete) +
                                " rows with an empty or corrupt field skipped, in " +
                                std::to_string(files_with_incomplete) + " files");
    if (fit.files == 0) continue;
    fit.min_distance = d.front();
    fit.max_distance = d.back();
    if (d.size() >= 2 && d.back() > d.front()) {
      Eigen::MatrixXd a(static_cast<long>(d.size()), 2);
      Eigen::VectorXd b(static_cast<long>(d.size()));
      for (size_t i = 0; i < d.size(); ++i) {
        a(static_cast<long>(i), 0) = 1.0;
        a(static_cast<long>(i), 1) = d[i];
        b(static_cast<long>(i)) = med[i];
      }
      const Eigen::Vector2d x = a.colPivHouseholderQr().solve(b);
      fit.offset = x(0);
      fit.scale = x(1);
    } else {
      fit.offset = med.front();
    }
    std::vector<double> res;
    for (const auto& [dist, e] : all) res.push_back(e - (fit.offset + fit.scale * dist));
    fit.sigma = mad(res);
    report.fits.push_back(fit);
  }
  return report;
}

std::string formatStaticRanging(const StaticRangingReport& r) {
  std::string out;
  char buf[200];
  std::snprintf(buf, sizeof buf, "%-8s %-16s %5s %7s %9s %10s %8s %11s\n", "cond", "group", "files",
                "ranges", "offset_m", "scale", "sigma_m", "range_m");
  out += buf;
  for (const auto& f : r.fits) {
    std::snprintf(buf, sizeof buf, "%-8s %-16s %5d %7ld %9.4f %10.6f %8.4f %5.0f-%-5.0f\n",
                  f.condition.c_str(), f.group.c_str(), f.files, f.ranges, f.offset, f.scale,
                  f.sigma, f.min_distance, f.max_distance);
    out += buf;
  }
  for (const auto& p : r.problems) out += "note: " + p + "\n";
  return out;
}

std::string formatCalibration(const CalibrationResult& r) {
  std::string out;
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "Calibrated from %ld ranges with a reference (%ld without); residual sigma "
                "%.4f m after the fit\n%-8s %-5s %9s %10s %8s %8s\n",
                r.samples, r.skipped, r.sigma, "anchor", "tag", "bias_m", "scale", "sigma_m",
                "ranges");
  out += buf;
  for (const auto& b : r.biases) {
    std::snprintf(buf, sizeof buf, "%-8d %-5s %9.4f %10.6f %8.4f %8ld\n", b.anchor_id,
                  b.tag_id ? std::to_string(*b.tag_id).c_str() : "*", b.bias, b.scale, b.sigma,
                  b.samples);
    out += buf;
  }
  for (const auto& [id, moved] : r.anchor_moved) {
    const uwb::Anchor* a = uwb::findAnchor(r.anchors, id);
    std::snprintf(buf, sizeof buf, "anchor %d estimated at (%.4f, %.4f, %.4f), moved %.4f m\n", id,
                  a->position.x(), a->position.y(), a->position.z(), moved);
    out += buf;
  }
  for (const auto& n : r.notes) out += "note: " + n + "\n";
  return out;
}

}  // namespace uwbloc::eval
