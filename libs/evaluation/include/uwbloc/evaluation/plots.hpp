// The run's pictures (PNG, drawn with OpenCV): trajectories over the map, error over time, the
// error CDF, per-anchor range residuals and the PF-IBAS swarm spread.
#pragma once

#include <string>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/evaluation/runner.hpp"

namespace uwbloc::eval {

/// One written picture: its file name inside plots/ and what it shows.
struct PlotFile {
  std::string file;
  std::string caption;
};

/// Writes the PNGs into `plots_dir` (created) and returns them in the order a report shows them:
/// - trajectories.png: the reference and every method on the map (occupancy grid, anchors) or,
///   without a map, on a blank grid; a scale bar either way;
/// - trajectory_<method>.png: the reference and one method;
/// - error_<method>.png: the planar error over time;
/// - error_cdf.png: every method's error CDF on one chart;
/// - range_residuals.png: range minus the distance from the reference, per anchor, over time,
///   marked by what the first NLOS-judging method did with each range;
/// - swarm_spread.png: PF-IBAS's swarm spread over time (methods that log it).
/// The palette is Okabe and Ito's, which colour-blind readers tell apart. The pictures are drawn
/// on up to `jobs` threads. Throws data::InputError when a file cannot be written.
std::vector<PlotFile> writePlots(const std::string& plots_dir, const data::Dataset& dataset,
                                 const std::vector<MethodSummary>& methods, int jobs = 1);

}  // namespace uwbloc::eval
