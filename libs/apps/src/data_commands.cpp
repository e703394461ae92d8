// `uwbloc import`, `simulate` and `augment`: the commands that write datasets.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "uwbloc/dataset/carmen_import.hpp"
#include "uwbloc/dataset/data_dir.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/librsf_import.hpp"
#include "uwbloc/dataset/plaza_import.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/evaluation/benchmark.hpp"
#include "uwbloc/evaluation/calibration.hpp"
#include "uwbloc/evaluation/sensitivity.hpp"

namespace uwbloc::apps {

namespace {

// Comma-separated numbers of an option, or an InputError naming it.
std::vector<double> splitNumbers(const std::string& text, const std::string& option) {
  std::vector<double> out;
  for (const auto& part : splitList(text)) {
    char* end = nullptr;
    const double v = std::strtod(part.c_str(), &end);
    if (part.empty() || end != part.c_str() + part.size() || !std::isfinite(v))
      throw data::InputError(option + ": '" + part + "' is not a number");
    out.push_back(v);
  }
  return out;
}

// The import's summary, then what loading the written dataset says about it (every command
// that reads it will say the same: the ranges against the reference, collapsed stamps, ...), so
// that the first look at one's data shows it.
void printSummary(const data::ImportSummary& s) {
  std::cout << "Imported " << s.ranges << " ranges from " << s.anchors << " anchors, " << s.scans
            << " scans and " << s.ground_truth_rows << " reference poses\nManifest: " << s.manifest
            << "\n";
  for (const auto& note : s.notes) std::cout << note << "\n";
  for (const auto& [reason, count] : s.skipped)
    std::cout << "Skipped " << count << " rows: " << reason << "\n";
  const data::Dataset ds = data::loadDataset(s.manifest, "");
  for (const auto& w : ds.warnings) std::cout << "WARNING: " << w << "\n";
  if (const auto w = data::referenceCoverageWarning(ds))
    std::cout << "WARNING: " << *w << ": run and compare refuse it (--allow-partial-reference)\n";
}

}  // namespace

void ImportCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "import", "Convert a public dataset into a rawlog, a ground-truth file and a manifest");
  auto* cmd = subcommand_;
  cmd->add_option("format", format_,
                  "source format: hanyang (one dynamic run folder), carmen (a .log or .log.gz), "
                  "plaza (the Plaza folder), lias (one UWB_*.csv file of the LIAS-CUHKSZ "
                  "planar set, dynamic or static), librsf (a libRSF text file: range2, "
                  "odom2diff, point2 lines) or csv (your own CSV files: --ranges, --anchors, ...)")
      ->required()
      ->check(CLI::IsMember({"hanyang", "carmen", "plaza", "lias", "librsf", "csv"}));
  cmd->add_option("source", source_,
                  "source folder or file (as given, or relative to the data directory), e.g. "
                  "hanyang_outdoor_uwb/LOS_TrajA_Case1; csv: the ranges file (or --ranges)");
  cmd->add_option("--out,-o", out_, "output folder")->required();
  cmd->add_option("--data-dir", data_dir_, "folder of public datasets");
  cmd->add_option("--tag-height", tag_height_,
                  "tag height [m] (hanyang: default 1.0; lias: default the motion capture's "
                  "median z)");
  cmd->add_option("--bias", lias_.bias_csv,
                  "lias: a per-link bias CSV (from 'uwbloc calibrate') to name in the manifest");
  cmd->add_option("--ranges", csv_.ranges,
                  "csv: ranges 't,anchor_id,range[,tag_id][,rx_power,fp_power]' (a header row of "
                  "these names may place them; anchor and tag ids may be numbers or names such "
                  "as a device's 1C8D, numbered on import and listed in ids.csv), or one column "
                  "per anchor under a header 't,<anchor>,<anchor>,...[,tag_id]' (range_A1, d1 "
                  "and the like name anchor A1 and 1; an empty, NaN or non-positive cell is no "
                  "range)");
  cmd->add_option("--anchors", csv_.anchors,
                  "csv: anchors 'id,x,y,z' (ids as in --ranges); 'id,x,y' puts them at the tag's "
                  "height, with a warning");
  cmd->add_option("--odometry", csv_.odometry,
                  "csv: odometry 't,dx,dy,dtheta' (increments), 't,x,y,theta' (poses) or "
                  "'t,v,omega' (velocities)");
  cmd->add_option("--odometry-kind", csv_.odometry_kind,
                  "csv: increments, poses or velocities; auto: from the header, the column "
                  "count, or dead reckoning against --reference")
      ->check(CLI::IsMember({"auto", "increments", "poses", "velocities"}))
      ->capture_default_str();
  cmd->add_option("--odometry-convention", csv_.odometry_convention,
                  "csv: how the odometry is written: as-written, clockwise (its y and turn "
                  "negated), degrees (its turn), mm or cm (its distances); auto: as written, "
                  "unless another of these follows the track of the ranges' own fixes where it "
                  "does not, which is taken (with a warning)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "as-written", "clockwise", "degrees", "mm", "cm"}));
  cmd->add_option("--time-unit", csv_.time_unit,
                  "csv: the unit of every file's time column; auto: seconds, unless a file's "
                  "median stamp would then be after the year 3000, where the first of ms, us "
                  "and ns that brings it before is taken (with a warning)")
      ->check(CLI::IsMember({"auto", "s", "ms", "us", "ns"}))
      ->capture_default_str();
  cmd->add_option("--range-unit", csv_.range_unit,
                  "csv: the unit of the ranges; auto: metres, unless their median is over 10 "
                  "times the anchors' largest spacing and over 100 m, where the one of cm and mm "
                  "that puts the tag among the anchors is taken (with a warning; an error when "
                  "neither or both do)")
      ->check(CLI::IsMember({"auto", "m", "cm", "mm"}))
      ->capture_default_str();
  cmd->add_option("--anchor-unit", csv_.anchor_unit,
                  "csv: the unit of the anchors' coordinates; auto: metres, unless the ranges "
                  "cannot be distances to anchors that far apart (two ranges of one tag falling "
                  "short of their anchors' distance apart) and one of mm, cm, inches and feet "
                  "alone makes them fit, which is taken (with a warning)")
      ->check(CLI::IsMember({"auto", "m", "cm", "mm", "in", "ft"}))
      ->capture_default_str();
  cmd->add_option("--imu", csv_.imu, "csv: IMU 't,gx,gy,gz,ax,ay,az' [rad/s, m/s^2]");
  cmd->add_option(
      "--reference", csv_.reference,
      "csv: reference poses, TUM or 't,x,y[,theta]' (without theta no heading is "
      "scored; theta in radians, or in degrees when only that turns as the travel "
      "does, with a warning); librsf: the ground-truth file (default: the _GT file beside the "
      "_Input file)");
  cmd->add_option("--scans", csv_.scans,
                  "csv: LiDAR scans, one a row: 't,angle_min,angle_increment,r0,r1,...'");
  cmd->add_option("--tag", tags_,
                  "csv: a tag on the robot 'id,x,y,z' [m], the id as the ranges write it (a "
                  "number or a name; repeat for several tags; default: tag 0 at the origin, at "
                  "--tag-height)");
  cmd->add_option("--scan-pose", scan_pose_, "csv: the scanner on the robot 'x,y,yaw[,height]'");
  cmd->add_option("--scan-max-range", csv_.scan_max_range,
                  "csv: the scanner's maximum range [m] (default: the longest range in the file)");
  cmd->add_option("--map", csv_.map, "csv: an occupancy map file for the methods that need one");
  cmd->add_option("--name", csv_.name, "csv: dataset name (default: the output folder's)");
  cmd->add_option("--yaw-offset", lias_.yaw_offset_deg,
                  "lias, static runs: heading = the README's yaw + this [deg] (default: the "
                  "motion capture's frame found on the dynamic run beside the Static folder)");
  cmd->add_option("--readme", lias_.readme,
                  "lias: the README with the anchor and tag coordinates (default: "
                  "Planar_Dataset/<Dynamic|Static>/README.md above the file)");
}

int ImportCommand::run() {
  data::ImportSummary s;
  if (format_ == "csv") {
    if (csv_.ranges.empty()) csv_.ranges = source_;
    for (const auto& t : tags_) {
      // The id may be a name (as the ranges' tag column writes it).
      const auto comma = t.find(',');
      const std::string id = t.substr(0, comma);
      const auto v = splitNumbers(comma == std::string::npos ? "" : t.substr(comma + 1), "--tag");
      if (id.empty() || v.size() != 3)
        throw data::InputError("--tag: expected 'id,x,y,z', got '" + t + "'");
      const Eigen::Vector3d at(v[0], v[1], v[2]);
      if (const auto number = data::integerId(id))
        csv_.tags[*number] = at;
      else
        csv_.tag_names[id] = at;
    }
    if (!scan_pose_.empty()) {
      const auto v = splitNumbers(scan_pose_, "--scan-pose");
      if (v.size() != 3 && v.size() != 4)
        throw data::InputError("--scan-pose: expected 'x,y,yaw[,height]', got '" + scan_pose_ +
                               "'");
      csv_.scan_pose = Eigen::Vector3d(v[0], v[1], v[2]);
      if (v.size() == 4) csv_.scan_height = v[3];
    }
    csv_.tag_height = tag_height_;
    s = data::importCsv(csv_, out_);
    printSummary(s);
    return kSuccess;
  }
  if (source_.empty()) throw data::InputError("import " + format_ + ": the source is required");
  const std::string src = data::resolveInputPath(source_, data::resolveDataDir(data_dir_));
  if (tag_height_) {
    hanyang_.tag_height = *tag_height_;
    lias_.tag_height = *tag_height_;
  }
  if (format_ == "hanyang")
    s = data::importHanyang(src, out_, hanyang_);
  else if (format_ == "lias")
    s = data::importLias(src, out_, lias_);
  else if (format_ == "librsf")
    s = data::importLibrsf(src, out_, csv_.reference);
  else if (format_ == "plaza")
    s = data::importPlaza(src, out_);
  else
    s = data::importCarmen(src, out_);
  printSummary(s);
  return kSuccess;
}

void ExportCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "export",
      "Write a dataset as plain CSV files (ranges, anchors, odometry increments, IMU, reference, "
      "scans) and print the 'uwbloc import csv' line that reads them back");
  subcommand_->add_option("--dataset,-d", dataset_, "dataset manifest (INI)")->required();
  subcommand_->add_option("--out,-o", out_, "output folder")->required();
  subcommand_->add_option("--data-dir", data_dir_, "folder of public datasets");
}

int ExportCommand::run() {
  const std::string data_dir = data::resolveDataDir(data_dir_);
  const auto ds = data::loadDataset(data::resolveInputPath(dataset_, data_dir), data_dir);
  const std::string args = data::exportCsv(ds, out_);
  std::cout << "Exported " << ds.name << " to " << out_
            << "\nRead it back with:\n  uwbloc import csv " << args << " -o DIR\n";
  return kSuccess;
}

void SimulateCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "simulate",
      "Simulate a scenario: writes a rawlog, ground truth (TUM and time x y phi), anchors, map "
      "and a manifest");
  subcommand_
      ->add_option("--scenario,-s", scenario_,
                   "scenario INI (as given, or in the project's datasets/scenarios/)")
      ->required();
  subcommand_->add_option("--out,-o", out_, "output folder")->required();
  subcommand_->add_option("--seed", seed_, "random seed; the same seed gives byte-identical files")
      ->capture_default_str();
}

int SimulateCommand::run() {
  const std::string path = data::resolveInputPath(scenario_, "");
  const auto sc = data::loadScenario(path);
  for (const auto& w : sc.warnings) std::cerr << "warning: " << path << ": " << w << "\n";
  const auto manifest = data::writeSimulation(sc, seed_, out_);
  std::cout << "Simulated " << sc.name << " (" << sc.duration << " s, seed " << seed_
            << ")\nManifest: " << manifest << "\n";
  return kSuccess;
}

void AugmentCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "augment", "Add simulated UWB ranges to a real LiDAR recording at its reference poses");
  auto* cmd = subcommand_;
  data::AugmentRequest& r = request_;
  cmd->add_option("--rawlog,-r", r.rawlog, "recording (rawlog)")->required();
  cmd->add_option("--reference,-p", r.reference, "reference poses: .tum, else 'time x y phi'")
      ->required();
  cmd->add_option("--anchors,-a", r.anchors_csv, "anchors CSV (id,x,y,z)")->required();
  cmd->add_option("--out,-o", out_, "output folder")->required();
  cmd->add_option("--scenario,-s", r.scenario,
                  "take the [uwb] model from this scenario (as given, or in the project's "
                  "datasets/scenarios/); its tag_<id> keys add tags on the robot (a recording "
                  "with its own ranges keeps them as tag 0)");
  cmd->add_option("--map", r.map,
                  "map for NLOS: a map file, or 'scans' to map the recording's own scans at the "
                  "reference poses (default: no NLOS)");
  cmd->add_option("--seed", r.seed, "random seed")->capture_default_str();
  cmd->add_flag("--allow-bad-time", r.allow_bad_time,
                "augment a recording whose timestamps have collapsed instead of refusing it");
  cmd->add_option("--max-gap", r.max_gap,
                  "no ranges where reference poses are further apart than this [s]")
      ->capture_default_str();
}

int AugmentCommand::run() {
  // A scenario is found as `simulate` finds it (as given, or in the project's scenarios).
  if (!request_.scenario.empty()) request_.scenario = data::resolveInputPath(request_.scenario, "");
  std::cout << "Manifest: " << data::writeAugmented(request_, out_) << "\n";
  return kSuccess;
}

void BenchmarkCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "benchmark",
      "Every dataset the data directory and the project provide (imported or simulated), every "
      "applicable method with its defaults, several seeds: one table of mean and worst-seed 2D "
      "RMSE and coverage (benchmark.md, benchmark.json)");
  auto* cmd = subcommand_;
  cmd->add_option("--data-dir", data_dir_,
                  "folder of public datasets (default: $UWBLOC_DATA_DIR, else ../shared/datasets)");
  cmd->add_option("--out,-o", out_, "work folder: imports, simulations and the tables")
      ->capture_default_str();
  cmd->add_option("--seeds", seeds_, "seeds 1..N per method")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  cmd->add_option("--methods,-m", methods_, "comma-separated method specs (default: all)");
  cmd->add_option("--datasets", datasets_,
                  "comma-separated name fragments: only the datasets whose name holds one (e.g. "
                  "hanyang,sim/office)");
}

int BenchmarkCommand::run() {
  eval::BenchmarkOptions o;
  o.data_dir = data::resolveDataDir(data_dir_);
  o.project_datasets = data::projectDatasetsDir();
  o.work_dir = out_;
  o.seeds = seeds_;
  o.methods = splitMethodSpecs(methods_);
  o.datasets = splitList(datasets_);
  eval::checkBenchmarkMethods(o.methods);  // before the imports, which take minutes
  // The tables go here even when no dataset needed importing (the demo alone).
  data::ensureDirectory(out_);
  const auto log = [](const std::string& line) { std::cerr << line << "\n"; };
  const auto cells = eval::runBenchmark(eval::prepareBenchmarkDatasets(o, log), o, log);
  const std::string md = eval::formatBenchmarkMarkdown(cells, seeds_);
  data::writeFileAtomic((std::filesystem::path(out_) / "benchmark.md").string(), md);
  data::writeFileAtomic((std::filesystem::path(out_) / "benchmark.json").string(),
                        eval::formatBenchmarkJson(cells, seeds_));
  std::cout << md << "Tables: " << out_ << "/benchmark.md, " << out_ << "/benchmark.json\n";
  return cells.empty() ? kNoResult : kSuccess;
}

void SensitivityCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "sensitivity",
      "On a simulated scenario made LOS-clean: inject a bias (0.5, 1, 3 m) on one anchor and on "
      "all, a range noise std (0.05 to 1 m), or a span in which every range is NLOS (10, 30, "
      "60 s); run each method with its defaults and with the true model given, and tabulate "
      "both RMSEs (sensitivity.md, sensitivity.json)");
  auto* cmd = subcommand_;
  cmd->add_option("--scenario,-s", scenario_,
                  "scenario INI (as given, or in the project's datasets/scenarios/)")
      ->capture_default_str();
  cmd->add_option("--out,-o", out_, "work folder: simulations and the tables")
      ->capture_default_str();
  cmd->add_option("--seeds", seeds_, "filter seeds 1..N per run")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  cmd->add_option("--duration", duration_, "simulated span [s]")
      ->capture_default_str()
      ->check(CLI::Range(10.0, 36000.0));
  cmd->add_option("--methods,-m", methods_,
                  "comma-separated method specs (default: graph-uwb-odom, uwb-ekf, uwb-pf, "
                  "fused-pf, pf-ibas)");
  cmd->add_option("--conditions", conditions_,
                  "comma-separated condition names as the table prints them, e.g. \"bias 0.5 m "
                  "on anchor 1,sigma 0.30 m\" (default: every condition)");
}

int SensitivityCommand::run() {
  eval::SensitivityOptions o;
  o.scenario = data::resolveInputPath(scenario_, "");
  o.work_dir = out_;
  o.seeds = seeds_;
  o.duration = duration_;
  if (!methods_.empty()) o.methods = splitMethodSpecs(methods_);
  if (!conditions_.empty()) o.conditions = splitList(conditions_);
  const auto log = [](const std::string& line) { std::cerr << line << "\n"; };
  const auto cells = eval::runSensitivity(o, log);
  const std::string md = eval::formatSensitivityMarkdown(cells);
  data::writeFileAtomic((std::filesystem::path(out_) / "sensitivity.md").string(), md);
  data::writeFileAtomic((std::filesystem::path(out_) / "sensitivity.json").string(),
                        eval::formatSensitivityJson(cells));
  std::cout << md << "Tables: " << out_ << "/sensitivity.md, " << out_ << "/sensitivity.json\n";
  return cells.empty() ? kNoResult : kSuccess;
}

}  // namespace uwbloc::apps

namespace uwbloc::apps {

void CalibrateCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "calibrate",
      "From recordings with a reference (static runs at known poses, or a run with motion "
      "capture): each anchor-tag link's (or anchor's) range bias, optionally scale, the range "
      "noise, and the positions of anchors marked unknown. Writes anchors.csv and bias.csv, which "
      "a manifest names with [anchors] anchors_csv and bias_csv");
  auto* cmd = subcommand_;
  cmd->add_option("manifests", manifests_, "dataset manifests (dataset.ini) with a reference");
  cmd->add_option("--static-ranging", static_ranging_,
                  "instead: a folder of static ranging at known distances (<condition>/<group>/"
                  "<D>m.csv, the Hanyang static layout, e.g. hanyang_outdoor_uwb/static): the "
                  "range error as offset + scale x distance per condition and group; writes "
                  "range_error_fit.csv");
  cmd->add_option("--out,-o", out_, "output folder")->required();
  cmd->add_option("--per", per_, "one bias per link (anchor and tag) or per anchor")
      ->check(CLI::IsMember({"link", "anchor"}))
      ->capture_default_str();
  cmd->add_flag("--scale", scale_, "also fit a range scale per group");
  cmd->add_option("--free-anchors", free_anchors_,
                  "comma-separated anchor ids whose x, y are unknown, or 'all'");
  cmd->add_option("--data-dir", data_dir_, "folder of public datasets");
}

int CalibrateCommand::run() {
  const std::string data_dir = data::resolveDataDir(data_dir_);
  if (!static_ranging_.empty()) {
    const auto report =
        eval::fitStaticRanging(data::resolveInputPath(static_ranging_, data_dir));
    data::ensureDirectory(out_);
    std::string csv = "condition,group,files,ranges,offset,scale,sigma,min_distance,max_distance\n";
    char buf[256];
    for (const auto& f : report.fits) {
      std::snprintf(buf, sizeof buf, "%s,%s,%d,%ld,%.5f,%.7f,%.5f,%g,%g\n", f.condition.c_str(),
                    f.group.c_str(), f.files, f.ranges, f.offset, f.scale, f.sigma,
                    f.min_distance, f.max_distance);
      csv += buf;
    }
    data::writeFileAtomic((std::filesystem::path(out_) / "range_error_fit.csv").string(), csv);
    std::cout << eval::formatStaticRanging(report) << "Written: " << out_
              << "/range_error_fit.csv\n";
    return report.fits.empty() ? kNoResult : kSuccess;
  }
  if (manifests_.empty())
    throw data::InputError("calibrate: give dataset manifests, or --static-ranging FOLDER");
  std::vector<data::Dataset> datasets;
  for (const auto& m : manifests_) {
    datasets.push_back(data::loadDataset(data::resolveInputPath(m, data_dir), data_dir, false));
    if (!datasets.back().manifest.biases.empty())
      std::cerr << "note: " << m << " names a bias file; calibration reads its raw ranges\n";
  }
  std::vector<const data::Dataset*> in;
  for (const auto& d : datasets) in.push_back(&d);
  eval::CalibrationOptions o;
  o.per_link = per_ == "link";
  o.scale = scale_;
  if (free_anchors_ == "all") {
    for (const auto& a : datasets.front().anchors) o.free_anchors.push_back(a.id);
  } else {
    for (const auto& id : splitList(free_anchors_)) {
      try {
        o.free_anchors.push_back(std::stoi(id));
      } catch (const std::exception&) {
        throw data::InputError("--free-anchors: '" + id + "' is not an anchor id");
      }
    }
  }
  const auto result = eval::calibrateRanges(in, o);
  data::ensureDirectory(out_);
  const std::filesystem::path out(out_);
  data::writeFileAtomic((out / "anchors.csv").string(), data::formatAnchorsCsv(result.anchors));
  data::writeFileAtomic((out / "bias.csv").string(), data::formatBiasCsv(result.biases));
  std::cout << eval::formatCalibration(result) << "Written: " << out_ << "/anchors.csv, " << out_
            << "/bias.csv\n";
  return kSuccess;
}

}  // namespace uwbloc::apps
