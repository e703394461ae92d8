// Our lidar-mcl against MRPT's own pf-localization (mrpt-apps), on the same rawlog and map, in
// the same run on the same machine: same particle count, same start box (GT +- 0.5 m, +- 20 deg)
// and the same likelihood-field settings. MRPT's estimates are read from its log and scored with
// our evaluation. Usage: bench_vs_mrpt [runs=10] [particles=300]
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/text_io.hpp"
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

}  // namespace

int main(int argc, char** argv) {
  const int runs = argc > 1 ? std::atoi(argv[1]) : 10;
  const int particles = argc > 2 ? std::atoi(argv[2]) : 300;
  const auto ds =
      data::loadDataset(std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini", "");
  const fs::path dir = fs::temp_directory_path() / "uwbloc_bench_vs_mrpt";
  fs::create_directories(dir);
  data::writeFileAtomic((dir / "pf.ini").string(), config(dir, particles));

  std::printf("MRPT UWB demo, %d particles, start box GT +- 0.5 m / +- 20 deg, %d runs each\n",
              particles, runs);
  std::printf("%-28s %8s %8s %8s %8s %10s\n", "method", "rmse_x", "rmse_y", "rmse_2d", "max_2d",
              "ms/step");
  // MRPT pf-localization: parse "Step k", "PDF estimation: (x,y,phideg)" and "Done in t ms".
  const std::regex step(R"(Step (\d+)\. Executing)"),
      pdf(R"(PDF estimation: \(([-\d.]+),([-\d.]+),([-\d.]+)deg\))"), done(R"(Done in ([\d.]+)ms)");
  double mrpt_rmse = 0, mrpt_x = 0, mrpt_y = 0, mrpt_max = 0, mrpt_ms = 0;
  int mrpt_ok = 0;
  for (int r = 0; r < runs; ++r) {
    const std::string cmd = "pf-localization " + (dir / "pf.ini").string() + " > " +
                            (dir / "log.txt").string() + " 2>&1";
    if (std::system(cmd.c_str()) != 0) {
      std::fprintf(stderr, "pf-localization failed (is mrpt-apps installed?); see %s\n",
                   (dir / "log.txt").c_str());
      break;
    }
    std::ifstream log(dir / "log.txt");
    std::vector<loc::PoseEstimate> traj;
    double ms = 0;
    long n_done = 0;
    long k = -1;
    for (std::string line; std::getline(log, line);) {
      std::smatch m;
      if (std::regex_search(line, m, step)) k = std::stol(m[1]);
      if (std::regex_search(line, m, done)) {
        ms += std::stod(m[1]);
        ++n_done;
      }
      if (std::regex_search(line, m, pdf) && k >= 0 &&
          static_cast<size_t>(k) < ds.step_times.size()) {
        loc::PoseEstimate e;
        e.t = ds.step_times[static_cast<size_t>(k)];
        e.pose << std::stod(m[1]), std::stod(m[2]), std::stod(m[3]) * M_PI / 180.0;
        traj.push_back(e);
      }
    }
    const auto metrics =
        eval::computeMetrics(eval::associate(traj, ds.ground_truth), traj, ds.ground_truth);
    mrpt_rmse += metrics.rmse_2d;
    mrpt_x += metrics.rmse_x;
    mrpt_y += metrics.rmse_y;
    mrpt_max += metrics.max_2d;
    mrpt_ms += n_done ? ms / n_done : 0;
    ++mrpt_ok;
  }
  if (mrpt_ok)
    std::printf("%-28s %8.3f %8.3f %8.3f %8.3f %10.3f\n", "MRPT pf-localization", mrpt_x / mrpt_ok,
                mrpt_y / mrpt_ok, mrpt_rmse / mrpt_ok, mrpt_max / mrpt_ok, mrpt_ms / mrpt_ok);
  const auto ours = eval::evaluateMethod(ds, "lidar-mcl:n=" + std::to_string(particles), runs, 1);
  std::printf("%-28s %8.3f %8.3f %8.3f %8.3f %10.3f\n",
              ("uwbloc lidar-mcl:n=" + std::to_string(particles)).c_str(), ours.metrics.rmse_x,
              ours.metrics.rmse_y, ours.metrics.rmse_2d, ours.metrics.max_2d, ours.ms_per_step);
  std::printf(
      "MRPT's ms/step is its own per-step timer ('Done in'), which excludes rawlog reading; ours "
      "is\n"
      "the time inside process() divided by the poses produced.\n");
  return 0;
}
