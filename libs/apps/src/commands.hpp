// The subcommand classes (internal to the apps library; the executable sees Command only).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "uwbloc/apps/command.hpp"
#include "uwbloc/dataset/csv_import.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/dataset/lias_import.hpp"
#include "uwbloc/dataset/simulator.hpp"
#include "uwbloc/evaluation/trajectory_eval.hpp"
#include "uwbloc/localization/optim/optimizers.hpp"
#include "uwbloc/nlos/train.hpp"

namespace uwbloc::apps {

/// "a,b,,c" -> {"a", "b", "c"}.
std::vector<std::string> splitList(const std::string& text);

/// Method specs, comma-separated: "a:k=v,k=v,b" -> {"a:k=v,k=v", "b"}. An item with '=' before
/// any ':' (k=v, or k=model:path) continues the previous spec.
std::vector<std::string> splitMethodSpecs(const std::string& list);

/// `name` reduced to letters, digits, '-' and '_' (anything else becomes '_'), `fallback` when
/// empty: a dataset's name made a directory name that cannot point elsewhere.
std::string safeName(const std::string& name, const std::string& fallback = "dataset");

/// Options of every command that runs methods on a dataset.
struct RunOptions {
  std::string dataset = "mrpt_uwb_demo.ini";
  std::string data_dir;
  std::string out;
  std::string config;
  std::vector<std::string> sets;
  uint64_t seed = 1;
  int repeat = 1;
  bool allow_bad_time = false;           ///< score a recording whose timestamps have collapsed
  bool allow_partial_reference = false;  ///< score against a reference covering < half the run
  bool strict = false;     ///< exit 3 when a method is flagged (no estimate, low coverage)
  std::string max_memory;  ///< e.g. "4G"; empty: half of the machine's memory
};

/// `run` (one method) and `compare` (several): replay, score, write the run directory, print
/// the table.
class RunMethodsCommand : public Command {
 public:
  explicit RunMethodsCommand(bool compare) : compare_(compare) {}
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  bool compare_;
  RunOptions options_;
  std::string methods_;
  int jobs_ = 1;
  bool plots_ = true;
  bool own_learning_ = false;
};

/// `import FORMAT SOURCE --out DIR`: a public dataset into a rawlog, a reference and a manifest.
class ImportCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::string format_, source_, out_, data_dir_;
  data::HanyangImportParams hanyang_;
  data::LiasImportParams lias_;
  std::optional<double> tag_height_;
  data::CsvImportRequest csv_;
  std::vector<std::string> tags_;
  std::string scan_pose_;
};

/// `export -d MANIFEST -o DIR`: a dataset as plain CSV files (the inverse of `import csv`).
class ExportCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::string dataset_, out_, data_dir_;
};

/// `simulate --scenario S --out DIR`.
class SimulateCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::string scenario_, out_;
  uint64_t seed_ = 1;
};

/// `augment`: simulated UWB ranges added to a real LiDAR recording.
class AugmentCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  data::AugmentRequest request_;
  std::string out_;
};

/// `bench-optimizers`: the PF-IBAS paper's Table 2.
class BenchOptimizersCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  int runs_ = 30;
  optim::RunSettings settings_;
  uint64_t seed_ = 1;
  int dim_ = 30;
  std::string optimizers_ = "bas,pso,ga,ba,ibas,ibas-fixed,ibas-scaled";
  std::string functions_ = "f1_sphere,f2_schwefel_2.22,f3_step,f4_rastrigin,f5_griewank";
};

/// `benchmark`: every dataset, every applicable method, defaults only, several seeds.
class BenchmarkCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::string data_dir_, out_ = "runs/benchmark", methods_, datasets_;
  int seeds_ = 5;
};

/// `sensitivity`: injected biases, noise and NLOS spans on a simulated scenario; defaults against
/// the true model.
class SensitivityCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::string scenario_ = "pfibas_room.ini", out_ = "runs/sensitivity", methods_, conditions_;
  int seeds_ = 3;
  double duration_ = 240.0;
};

/// `methods`: every registered method with its parameters, defaults and meaning.
class MethodsCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  bool limits_ = false;
};

/// `nlos train|eval|cv|cross`: NLOS identification and range-error correction.
class NlosCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  CLI::App *train_ = nullptr, *eval_ = nullptr, *cv_ = nullptr, *cross_ = nullptr;
  std::vector<std::string> files_;
  std::string data_dir_, out_, model_path_, features_ = "auto", model_types_ = "trees-density",
                                            centre_ = "none";
  nlos::TrainParams base_;
  int folds_ = 5, repeats_ = 5;
  double target_weight_ = 0.0;
  std::vector<int> shots_{0, 10, 50, 200};
};

/// `calibrate MANIFEST... --out DIR`: range bias, scale and noise, and unknown anchors, from
/// recordings with a reference.
class CalibrateCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::vector<std::string> manifests_;
  std::string out_, data_dir_, per_ = "link", free_anchors_, static_ranging_;
  bool scale_ = false;
};

/// `evaluate --reference REF --estimate A.tum ...`: trajectories from any source scored as
/// compare scores its own (APE raw and aligned, RPE, heading), with evo's statistics.
class EvaluateCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  std::string reference_, out_, data_dir_, align_ = "se2", delta_ = "1m",
                                           association_ = "interpolate";
  std::vector<std::string> estimates_;
  std::optional<double> max_diff_;
  double sparse_step_ = eval::Association{}.sparse_step;
  bool plots_ = true;
};

/// `sweep plan` (one command per dataset x method x seed) and `sweep merge DIR...`.
class SweepCommand : public Command {
 public:
  void declare(CLI::App& parser) override;
  int run() override;

 private:
  CLI::App *plan_ = nullptr, *merge_ = nullptr;
  std::string datasets_, methods_, out_, data_dir_, merge_out_ = "runs/sweep";
  std::vector<std::string> sets_, dirs_;
  int seeds_ = 1;
  uint64_t seed_ = 1;
};

}  // namespace uwbloc::apps
