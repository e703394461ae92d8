// Our estimators against MRPT's own apps (mrpt-apps) on the MRPT UWB demo, in the same run on
// the same machine, MRPT's estimates read from its console output and scored with our
// evaluation:
// - lidar-mcl against pf-localization: same particle count, same start box (GT +- 0.5 m,
//   +- 20 deg) and the same likelihood-field settings;
// - uwb-pf (and uwb-ekf) against ro-localization, run with the configuration MRPT ships for this
//   very log (config_files/ro-localization/UWB_localization_demo.ini: 15000 particles, beacon
//   std 0.17 m, start box +- 0.5 m with any heading), and with that file at our particle count.
// Usage: bench_vs_mrpt [runs=10] [particles=300] [ro_particles=15000]
#include <Eigen/Geometry>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <vector>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/text_io.hpp"
#include "uwbloc/evaluation/report.hpp"
#include "uwbloc/evaluation/runner.hpp"

namespace fs = std::filesystem;
using namespace uwbloc;

namespace {

std::string config(const fs::path& dir, int particles) {
  std::ostringstream c;
  c << "[KLD_options]\nKLD_minSampleSize=" << particles << "\nKLD_maxSampleSize=" << particles
    << "\n[PF_options]\nPF_algorithm=0\nresamplingMethod=0\nadaptiveSampleSize=0\nBETA=0.5\n"
       "sampleSize=1\n[LocalizationExperiment]\n"
       "map_file=/usr/share/mrpt/datasets/uwb_ro-localization_demo_map.gridmap.gz\n"
       "rawlog_file=/usr/share/mrpt/datasets/uwb_ro-localization_demo.rawlog\n"
    << "logOutput_dir=" << (dir / "out").string()
    << "\n3DSceneFrequency=-1\nexperimentRepetitions=1\n"
    << "particles_count=" << particles
    << "\ninit_PDF_mode=1\ninit_PDF_min_x=-0.5\ninit_PDF_max_x=0.5\ninit_PDF_min_y=-0.5\n"
       "init_PDF_max_y=0.5\ninit_PDF_min_phi_deg=-20\ninit_PDF_max_phi_deg=20\n"
       "SHOW_PROGRESS_3D_REAL_TIME=0\nSHOW_PROGRESS_IN_WINDOW=0\n[MetricMap]\noccupancyGrid_count="
       "1\n"
       "[MetricMap_occupancyGrid_00_likelihoodOpts]\nlikelihoodMethod=4\nLF_decimation=20\n"
       "LF_stdHit=0.20\nLF_maxCorrsDistance=0.20\nLF_zHit=0.90\nLF_zRandom=0.10\nLF_maxRange=30\n";
  return c.str();
}

// The configuration MRPT ships for the demo, with absolute paths, no log files and no 3D scenes.
// ro-localization works in the beacons' frame; `origin` receives the start pose it states there
// ([OdometryEstimation] odometry_X/Y/PHI), the origin of the ground truth's (and our) frame.
std::string roConfig(int particles, Eigen::Vector3d& origin) {
  const std::string shipped =
      "/usr/share/mrpt/config_files/ro-localization/UWB_localization_demo.ini";
  std::ifstream in(shipped);
  if (!in) return {};
  std::ostringstream out;
  origin.setZero();
  const std::regex start(R"(^odometry_(X|Y|PHI)\s*=\s*([-\d.]+))");
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (std::regex_search(line, m, start))
      origin(m[1] == "X"   ? 0
             : m[1] == "Y" ? 1
                           : 2) = std::stod(m[2]) * (m[1] == "PHI" ? M_PI / 180.0 : 1.0);
    if (line.rfind("sampleSize=", 0) == 0) line = "sampleSize=" + std::to_string(particles);
    if (line.rfind("logOutput_dir=", 0) == 0) line = "logOutput_dir=";
    if (line.rfind("3DSceneFrequency=", 0) == 0) line = "3DSceneFrequency=-1";
    const auto rel = line.find("../../datasets/");
    if (rel != std::string::npos) line.replace(rel, 15, "/usr/share/mrpt/datasets/");
    out << line << "\n";
  }
  return out.str();
}

struct Row {
  double x = 0, y = 0, rmse = 0, max = 0, ms = 0;
  int runs = 0;
  std::vector<double> each;  ///< rmse_2d of every run
  void add(const eval::Metrics& m, double ms_per_step) {
    each.push_back(m.rmse_2d);
    x += m.rmse_x;
    y += m.rmse_y;
    rmse += m.rmse_2d;
    max += m.max_2d;
    ms += ms_per_step;
    ++runs;
  }
  void print(const std::string& name) const {
    if (!runs) return;
    std::printf("%-36s %8.3f %8.3f %8.3f %8.3f %10.3f   runs:", name.c_str(), x / runs, y / runs,
                rmse / runs, max / runs, ms / runs);
    for (double v : each) std::printf(" %.3f", v);
    std::printf("\n");
  }
};

void printOurs(const data::Dataset& ds, const std::string& spec, int runs) {
  const auto ours = eval::evaluateMethod(ds, spec, runs, 1);
  std::printf("%-36s %8.3f %8.3f %8.3f %8.3f %10.3f\n", ("uwbloc " + spec).c_str(),
              ours.metrics.rmse_x, ours.metrics.rmse_y, ours.metrics.rmse_2d, ours.metrics.max_2d,
              ours.ms_per_step);
}

// How to read one MRPT app's console output: a line naming the step, the per-step timer and the
// pose estimate in degrees, and the pose of our frame's origin in the app's frame.
struct MrptLog {
  std::regex step, done, pdf;
  long (*step_index)(long);  ///< from the number the step line carries to our step index
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
};

// Runs `command` (which writes `log_path`) `runs` times and scores every run. The first run's
// path is saved as `tum_path` (TUM, our frame), for `uwbloc evaluate`.
Row runMrpt(const data::Dataset& ds, const std::string& command, const fs::path& log_path,
            const MrptLog& fmt, int runs, const fs::path& tum_path) {
  Row row;
  const Eigen::Rotation2Dd to_ours(-fmt.origin.z());
  for (int r = 0; r < runs; ++r) {
    if (std::system(command.c_str()) != 0) {
      std::fprintf(stderr, "'%s' failed (is mrpt-apps installed?); see %s\n", command.c_str(),
                   log_path.c_str());
      break;
    }
    std::ifstream log(log_path);
    std::vector<loc::PoseEstimate> traj;
    double ms = 0;
    long n_done = 0, k = -1;
    for (std::string line; std::getline(log, line);) {
      std::smatch m;
      if (std::regex_search(line, m, fmt.step)) k = fmt.step_index(std::stol(m[1]));
      if (std::regex_search(line, m, fmt.done)) {
        ms += std::stod(m[1]);
        ++n_done;
      }
      if (std::regex_search(line, m, fmt.pdf) && k >= 0 &&
          static_cast<size_t>(k) < ds.step_times.size()) {
        loc::PoseEstimate e;
        e.t = ds.step_times[static_cast<size_t>(k)];
        const Eigen::Vector2d p(std::stod(m[1]), std::stod(m[2]));
        e.pose << to_ours * (p - fmt.origin.head<2>()),
            std::stod(m[3]) * M_PI / 180.0 - fmt.origin.z();
        traj.push_back(e);
      }
    }
    if (r == 0) data::writeFileAtomic(tum_path.string(), eval::formatTrajectoryTum(traj));
    row.add(eval::computeMetrics(eval::associate(traj, ds.ground_truth), traj, ds.ground_truth),
            n_done ? ms / n_done : 0.0);
  }
  return row;
}

// MRPT ro-localization: "RAWLOG_ENTRY: e" (e = 2k + 1 after step k's action and observations;
// 0 for the first), then "Done! in t ms" and "PDF est: (x,y,phideg)", in the beacons' frame.
Row runRoLocalization(const data::Dataset& ds, const fs::path& dir, int particles, int runs) {
  MrptLog fmt{std::regex(R"(RAWLOG_ENTRY: (\d+))"), std::regex(R"(Done! in ([\d.]+)ms)"),
              std::regex(R"(PDF est: \(([-\d.]+),([-\d.]+),([-\d.]+)deg\))"),
              [](long entry) { return entry / 2; }};
  const std::string cfg = roConfig(particles, fmt.origin);
  if (cfg.empty()) {
    std::fprintf(stderr, "MRPT's ro-localization demo configuration is missing (mrpt-common)\n");
    return {};
  }
  data::writeFileAtomic((dir / "ro.ini").string(), cfg);
  return runMrpt(ds, "cd " + dir.string() + " && ro-localization ro.ini > ro_log.txt 2>&1",
                 dir / "ro_log.txt", fmt, runs,
                 dir / ("ro_localization_n" + std::to_string(particles) + ".tum"));
}

}  // namespace

int main(int argc, char** argv) {
  const int runs = argc > 1 ? std::atoi(argv[1]) : 10;
  const int particles = argc > 2 ? std::atoi(argv[2]) : 300;
  const int ro_particles = argc > 3 ? std::atoi(argv[3]) : 15000;
  const auto ds =
      data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  const fs::path dir = fs::temp_directory_path() / "uwbloc_bench_vs_mrpt";
  fs::create_directories(dir);
  data::writeFileAtomic((dir / "pf.ini").string(), config(dir, particles));

  std::printf("MRPT UWB demo, %d particles, start box GT +- 0.5 m / +- 20 deg, %d runs each\n",
              particles, runs);
  std::printf("%-36s %8s %8s %8s %8s %10s\n", "method", "rmse_x", "rmse_y", "rmse_2d", "max_2d",
              "ms/step");
  // MRPT pf-localization: "Step k", "Done in t ms" and "PDF estimation: (x,y,phideg)".
  const MrptLog pf_log{std::regex(R"(Step (\d+)\. Executing)"), std::regex(R"(Done in ([\d.]+)ms)"),
                       std::regex(R"(PDF estimation: \(([-\d.]+),([-\d.]+),([-\d.]+)deg\))"),
                       [](long step) { return step; }};
  const Row mrpt = runMrpt(
      ds,
      "pf-localization " + (dir / "pf.ini").string() + " > " + (dir / "log.txt").string() + " 2>&1",
      dir / "log.txt", pf_log, runs, dir / "pf_localization.tum");
  mrpt.print("MRPT pf-localization");
  printOurs(ds, "lidar-mcl:n=" + std::to_string(particles), runs);

  std::printf("\nRange-only: MRPT ro-localization with its shipped demo configuration\n");
  runRoLocalization(ds, dir, ro_particles, runs)
      .print("MRPT ro-localization n=" + std::to_string(ro_particles));
  if (ro_particles != particles)
    runRoLocalization(ds, dir, particles, runs)
        .print("MRPT ro-localization n=" + std::to_string(particles));
  // ro-localization starts from the start position +- 0.5 m with any heading; ours in the same
  // box with the heading unknown too (init_theta=180), at both particle counts, then as tracked.
  printOurs(ds, "uwb-pf:init_theta=180,n=" + std::to_string(ro_particles), runs);
  if (ro_particles != particles)
    printOurs(ds, "uwb-pf:init_theta=180,n=" + std::to_string(particles), runs);
  // The wide start handled as MRPT's KLD option would: many particles until the cloud
  // converges, then the tracking count.
  printOurs(ds, "uwb-pf:init_theta=180,init_n=3000,n=" + std::to_string(particles), runs);
  printOurs(ds, "pf-ibas:init_theta=180,init_n=3000", runs);
  printOurs(ds, "uwb-pf:n=" + std::to_string(particles), runs);
  printOurs(ds, "uwb-ekf", 1);
  std::printf(
      "MRPT's ms/step is its own per-step timer ('Done in'), which excludes rawlog reading; ours "
      "is\n"
      "the time inside process() divided by the poses produced.\n");
  return 0;
}
