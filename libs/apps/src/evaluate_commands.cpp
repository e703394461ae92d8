// `uwbloc evaluate` (any trajectory files against a reference) and `uwbloc sweep plan|merge`
// (a compare split into independent jobs for GNU parallel, xargs or a Slurm array, and merged).
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "commands.hpp"
#include "uwbloc/dataset/data_dir.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/evaluation/trajectory_eval.hpp"

namespace fs = std::filesystem;

namespace uwbloc::apps {

namespace {

// A trajectory file: TUM ("t x y z qx qy qz qw") or "t x y phi", told apart by the column count
// of the first data row. Throws data::InputError naming the file.
std::vector<data::TimedPose> readTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw data::InputError(path + ": cannot open the trajectory");
  data::GroundTruthFormat format = data::GroundTruthFormat::kNone;
  for (std::string line; std::getline(in, line);) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream row(line);
    int columns = 0;
    for (std::string field; row >> field;) ++columns;
    if (columns == 8)
      format = data::GroundTruthFormat::kTum;
    else if (columns == 4)
      format = data::GroundTruthFormat::kTimeXyPhi;
    else
      throw data::InputError(path + ": the first row has " + std::to_string(columns) +
                             " columns; expected 8 (TUM: t x y z qx qy qz qw) or 4 (t x y phi)");
    break;
  }
  if (format == data::GroundTruthFormat::kNone) throw data::InputError(path + ": no pose rows");
  auto poses = data::readGroundTruth(path, format);
  if (poses.empty()) throw data::InputError(path + ": no pose rows");
  return poses;
}

// A file whose every heading is exactly zero carries none (a position-only method's output).
bool hasHeading(const std::vector<data::TimedPose>& poses) {
  return std::any_of(poses.begin(), poses.end(), [](const auto& p) { return p.pose.z() != 0.0; });
}

std::string stem(const std::string& path) {
  std::string s = fs::path(path).filename().string();
  for (const char* ext : {".tum", ".txt", ".csv"})
    if (s.size() > std::strlen(ext) &&
        s.compare(s.size() - std::strlen(ext), std::string::npos, ext) == 0)
      return s.substr(0, s.size() - std::strlen(ext));
  return s;
}

nlohmann::json statsJson(const eval::ErrorStats& s) {
  auto n = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  return {{"n", s.n},        {"rmse", n(s.rmse)}, {"mean", n(s.mean)}, {"median", n(s.median)},
          {"std", n(s.std)}, {"min", n(s.min)},   {"max", n(s.max)},   {"sse", n(s.sse)}};
}

// Single-quoted for a POSIX shell.
std::string shellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace

void EvaluateCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "evaluate",
      "Score trajectory files from any source (TUM or 't x y phi') against a reference: APE raw "
      "and aligned, RPE, heading; the same table, metrics.json and plots as compare");
  auto* cmd = subcommand_;
  cmd->add_option("--reference,-r", reference_,
                  "the reference: a trajectory file (TUM or 't x y phi'), or a dataset manifest "
                  "(its ground truth, map and anchors)")
      ->required();
  cmd->add_option("--estimate,-e", estimates_, "trajectory files to score (TUM or 't x y phi')")
      ->required()
      ->expected(1, -1);
  cmd->add_option("--out,-o", out_, "run directory to write (default: runs/evaluate_<reference>)");
  cmd->add_option("--align", align_,
                  "alignment of the aligned APE: se2 (the rigid motion that minimises it, "
                  "Umeyama), se2-origin (first poses made equal) or none")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "se2", "se2-origin"}));
  cmd->add_option("--delta", delta_, "RPE stretch: metres of reference path (1m) or seconds (2s)")
      ->capture_default_str();
  cmd->add_option("--association", association_,
                  "interpolate: the reference interpolated at each estimate's time (as compare); "
                  "nearest: the nearest reference pose (as evo)")
      ->capture_default_str()
      ->check(CLI::IsMember({"interpolate", "nearest"}));
  cmd->add_option("--max-diff", max_diff_,
                  "association tolerance [s]: longest reference gap to interpolate over, or "
                  "farthest nearest pose (default: the manifest's gt_max_gap, else 1 s for "
                  "interpolate and 0.01 s for nearest)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--sparse-step", sparse_step_,
                  "interpolate: a reference whose median step exceeds this is not interpolated; "
                  "the estimates are, at its stamps [s] (as compare)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cmd->add_option("--data-dir", data_dir_, "folder of public datasets (for a manifest reference)");
  cmd->add_flag("--plots,!--no-plots", plots_, "write plots/ (default: on)");
}

int EvaluateCommand::run() {
  const eval::Alignment alignment = eval::parseAlignment(align_);
  eval::RpeDelta delta;
  try {
    delta = eval::parseRpeDelta(delta_);
  } catch (const std::invalid_argument& e) {
    throw data::InputError(std::string("--delta: ") + e.what());
  }
  data::Dataset ds;
  const bool manifest = fs::path(reference_).extension() == ".ini";
  if (manifest) {
    const std::string data_dir = data::resolveDataDir(data_dir_);
    ds = data::loadDataset(data::resolveInputPath(reference_, data_dir), data_dir);
    if (ds.ground_truth.empty())
      throw data::InputError(reference_ + ": the dataset has no ground truth to score against");
  } else {
    ds.name = stem(reference_);
    ds.ground_truth = readTrajectory(reference_);
    ds.start_time = ds.ground_truth.front().t;
    ds.end_time = ds.ground_truth.back().t;
    ds.manifest.reference_heading = hasHeading(ds.ground_truth);
    ds.manifest.gt_max_gap = association_ == "nearest" ? 0.01 : 1.0;
  }
  if (max_diff_)
    ds.manifest.gt_max_gap = *max_diff_;
  else if (manifest && association_ == "nearest")
    ds.manifest.gt_max_gap = 0.01;
  const eval::Association assoc{association_ == "interpolate", ds.manifest.gt_max_gap,
                                sparse_step_};

  std::vector<eval::MethodSummary> summaries;
  nlohmann::json ape = nlohmann::json::object();
  std::set<std::string> names;
  for (const auto& path : estimates_) {
    const auto poses = readTrajectory(path);
    const bool heading = hasHeading(poses);
    eval::MethodSummary m;
    m.spec = stem(path);
    for (int k = 2; !names.insert(m.spec).second; ++k)
      m.spec = stem(path) + "_" + std::to_string(k);
    m.name = "trajectory";
    m.runs = 1;
    for (const auto& p : poses)
      m.trajectory.push_back({p.t, p.pose, Eigen::Matrix3d::Identity(), heading});
    auto pairs = eval::associatePoses(m.trajectory, ds.ground_truth, assoc);
    // Against a reference without heading, no estimate's heading can be judged: the RPE then
    // compares displacements in the map frame, and no yaw is scored.
    if (!ds.manifest.reference_heading)
      for (auto& p : pairs) p.heading = false;
    m.metrics = eval::computeMetrics(eval::errorSamples(pairs), m.trajectory, ds.ground_truth,
                                     std::max(assoc.max_diff, 1e-9), ds.manifest.reference_heading);
    const auto score = eval::scoreTrajectory(pairs, alignment, delta);
    m.metrics.rmse_2d_aligned = score.ape_aligned.rmse;
    m.metrics.rpe_trans_rmse = score.rpe.trans.rmse;
    m.metrics.rpe_rot_rmse_deg = ds.manifest.reference_heading ? score.rpe.rot_deg.rmse : NAN;
    m.metrics.alignment = eval::toString(alignment);
    m.metrics.rpe_delta = eval::toString(delta);
    m.seed_runs.push_back({0, m.metrics.rmse_2d, m.metrics.coverage, m.metrics.max_2d});
    m.ms_per_step = NAN;
    m.realtime_factor = NAN;
    if (pairs.empty())
      std::fprintf(stderr, "warning: %s: no pose overlaps the reference in time (tolerance %g s)\n",
                   path.c_str(), assoc.max_diff);
    ape[m.spec] = {
        {"file", path},
        {"pairs", score.pairs},
        {"association", association_},
        {"max_diff_s", assoc.max_diff},
        {"alignment", eval::toString(alignment)},
        {"alignment_transform", {score.alignment.x(), score.alignment.y(), score.alignment.z()}},
        {"ape", statsJson(score.ape)},
        {"ape_aligned", statsJson(score.ape_aligned)},
        {"yaw_deg", statsJson(score.yaw_deg)},
        {"rpe_delta", eval::toString(delta)},
        {"rpe_trans", statsJson(score.rpe.trans)},
        {"rpe_rot_deg", statsJson(score.rpe.rot_deg)}};
    summaries.push_back(std::move(m));
  }
  const std::string out = out_.empty() ? "runs/evaluate_" + safeName(ds.name) : out_;
  const eval::RunDirectoryLock lock(out);
  eval::RunInfo info;
  info.dataset_manifest = reference_;
  info.plots = plots_;
  info.extra_files = {{"ape.json", ape.dump(2) + "\n"}};
  info.association = assoc;
  eval::writeRunDirectory(out, ds, summaries, info);
  std::cout << eval::formatTable(ds, summaries, {}, assoc);
  std::cout << "Run directory: " << out << "\n";
  long scored = 0;
  for (const auto& m : summaries) scored += m.metrics.associated > 0;
  return scored > 0 ? kSuccess : kNoResult;
}

void SweepCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "sweep", "Split a compare into independent runs for other machines, and merge them");
  subcommand_->require_subcommand(1);
  plan_ = subcommand_->add_subcommand(
      "plan",
      "Print one self-contained command per (dataset, method, seed): a job list for GNU "
      "parallel, xargs -P or a Slurm array");
  plan_->add_option("--datasets", datasets_, "comma-separated dataset manifests")->required();
  plan_->add_option("--methods", methods_, "comma-separated method specs (as compare's)")
      ->required();
  plan_->add_option("--seeds", seeds_, "how many seeds per method (seed, seed+1, ...)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  plan_->add_option("--seed", seed_, "the first seed")->capture_default_str();
  plan_->add_option("--out,-o", out_, "folder under which every run writes its directory")
      ->required();
  plan_->add_option("--data-dir", data_dir_, "folder of public datasets, passed to every run");
  plan_->add_option("--set", sets_, "method.key=value, passed to every run (repeatable)");
  merge_ = subcommand_->add_subcommand(
      "merge",
      "Combine the run directories of a sweep into one table and metrics.json per dataset");
  merge_->add_option("dirs", dirs_, "run directories, or folders holding them")->required();
  merge_->add_option("--out,-o", merge_out_, "where the merged files go")->capture_default_str();
}

int SweepCommand::run() {
  if (plan_->parsed()) {
    // The executable's own path, so that a job runs the same build wherever its shell starts.
    std::string self = "uwbloc";
    std::error_code ec;
    if (const auto p = fs::read_symlink("/proc/self/exe", ec); !ec) self = p.string();
    const auto methods = splitMethodSpecs(methods_);
    const auto datasets = splitList(datasets_);
    if (methods.empty() || datasets.empty())
      throw data::InputError("sweep plan: --datasets and --methods must name at least one each");
    const std::string data_dir = data_dir_.empty() ? "" : fs::absolute(data_dir_).string();
    for (size_t d = 0; d < datasets.size(); ++d) {
      // Found now, so that a typo fails here and not on every machine of the sweep.
      const std::string manifest =
          fs::absolute(data::resolveInputPath(datasets[d], data::resolveDataDir(data_dir_)))
              .string();
      if (!fs::is_regular_file(manifest))
        throw data::InputError(datasets[d] +
                               ": no such dataset manifest (looked up as given, in "
                               "the data directory and in datasets/)");
      char dlabel[32];
      std::snprintf(dlabel, sizeof dlabel, "d%02zu_", d);
      for (size_t m = 0; m < methods.size(); ++m) {
        char mlabel[32];
        std::snprintf(mlabel, sizeof mlabel, "m%03zu_", m);
        for (int s = 0; s < seeds_; ++s) {
          const uint64_t seed = seed_ + static_cast<uint64_t>(s);
          const fs::path dir = fs::absolute(out_) / (dlabel + eval::fileLabel(stem(datasets[d]))) /
                               (mlabel + eval::fileLabel(methods[m])) /
                               ("seed" + std::to_string(seed));
          std::string cmd = shellQuote(self) + " compare -d " + shellQuote(manifest) +
                            " --methods " + shellQuote(methods[m]) + " --seed " +
                            std::to_string(seed) + " --repeat 1 --jobs 1 --no-plots --out " +
                            shellQuote(dir.string());
          if (!data_dir.empty()) cmd += " --data-dir " + shellQuote(data_dir);
          for (const auto& s2 : sets_) cmd += " --set " + shellQuote(s2);
          std::cout << cmd << "\n";
        }
      }
    }
    return kSuccess;
  }
  // Merge: every metrics.json found, grouped by dataset, then by method (first-seen order,
  // which is the plan's: its directory names sort in plan order), seeds in order.
  std::vector<fs::path> files;
  for (const auto& d : dirs_) {
    if (fs::is_regular_file(fs::path(d) / "metrics.json")) {
      files.push_back(fs::path(d) / "metrics.json");
      continue;
    }
    if (!fs::is_directory(d)) throw data::InputError(d + ": not a directory");
    for (const auto& e : fs::recursive_directory_iterator(d))
      if (e.is_regular_file() && e.path().filename() == "metrics.json") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty())
    throw data::InputError("sweep merge: no metrics.json under the directories given");
  std::vector<std::string> dataset_order;
  std::map<std::string, std::vector<std::pair<std::string, std::string>>> by_dataset;
  for (const auto& f : files) {
    std::ifstream in(f);
    std::ostringstream text;
    text << in.rdbuf();
    std::string name;
    try {
      name = nlohmann::json::parse(text.str()).at("dataset").get<std::string>();
    } catch (const nlohmann::json::exception& e) {
      throw data::InputError(f.string() + ": not a metrics.json: " + e.what());
    }
    if (!by_dataset.count(name)) dataset_order.push_back(name);
    by_dataset[name].emplace_back(f.string(), text.str());
  }
  const std::string out = merge_out_;
  data::ensureDirectory(out);
  for (const auto& name : dataset_order) {
    const std::string text = eval::mergeMetricsJson(by_dataset[name]);
    const fs::path dir = fs::path(out) / safeName(name);
    data::ensureDirectory(dir.string());
    data::writeFileAtomic((dir / "metrics.json").string(), text);
    const std::string table = eval::formatTableFromJson(text);
    data::writeFileAtomic((dir / "report.txt").string(), table);
    std::cout << table << "Merged " << by_dataset[name].size() << " run directories into "
              << dir.string() << "\n";
  }
  return kSuccess;
}

}  // namespace uwbloc::apps
