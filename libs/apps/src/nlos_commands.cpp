// `uwbloc nlos train|eval|cv|cross`: the NLOS classifier and range-error regressor.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <numeric>

#include "commands.hpp"
#include "uwbloc/dataset/data_dir.hpp"
#include "uwbloc/nlos/train.hpp"

namespace uwbloc::apps {
namespace {

struct ModelChoice {
  std::string name;
  nlos::TrainParams params;
};

// "trees-density", "trees-logistic", "logreg".
ModelChoice modelChoice(const std::string& name, const nlos::TrainParams& base) {
  ModelChoice c{name, base};
  if (name == "trees-density") {
    c.params.kind = nlos::Model::Kind::kTrees, c.params.objective = "density";
  } else if (name == "trees-logistic") {
    c.params.kind = nlos::Model::Kind::kTrees, c.params.objective = "logistic";
  } else if (name == "logreg") {
    c.params.kind = nlos::Model::Kind::kLogistic;
  } else {
    throw nlos::DataError("unknown model '" + name +
                          "' (choose trees-density, trees-logistic, logreg)");
  }
  return c;
}

void printHeader() {
  std::printf("%-34s %-15s %6s %6s %6s %6s %6s %6s  %-22s %s\n", "test", "model", "rows", "acc",
              "prec", "recall", "F1", "AUC", "confusion tp/fp/tn/fn",
              "NLOS err RMSE before->after [m]");
}

void printScores(const std::string& test, const std::string& model, const nlos::Scores& s) {
  char conf[64];
  std::snprintf(conf, sizeof conf, "%ld/%ld/%ld/%ld", s.tp, s.fp, s.tn, s.fn);
  std::printf("%-34s %-15s %6ld %6.3f %6.3f %6.3f %6.3f %6.3f  %-22s", test.c_str(), model.c_str(),
              s.n, s.accuracy, s.precision, s.recall, s.f1, s.auc, conf);
  if (s.nlos_error_rows)
    std::printf(" %.3f -> %.3f (all: %.3f -> %.3f)", s.nlos_rmse_before, s.nlos_rmse_after,
                s.rmse_before, s.rmse_after);
  std::printf("\n");
  std::fflush(stdout);
}

// The file's name, with its folder's when the name alone says nothing (range_features.csv).
std::string baseName(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return path;
  const std::string name = path.substr(slash + 1);
  if (name != "range_features.csv" || slash == 0) return name;
  const auto parent = path.find_last_of('/', slash - 1);
  return path.substr(parent == std::string::npos ? 0 : parent + 1);
}

}  // namespace

void NlosCommand::declare(CLI::App& parser) {
  subcommand_ = parser.add_subcommand(
      "nlos",
      "NLOS identification and range-error correction from signal features: train a model, "
      "score it, cross-validate it within an environment, or test its transfer to another");
  subcommand_->require_subcommand(1);
  auto data = [&](CLI::App* c, bool many) {
    c->add_option("--data", files_,
                  many ? "labelled range files: Ghent features CSVs or range_features.csv "
                         "with an nlos column (as given, or relative to the data directory)"
                       : "one labelled range file")
        ->required();
    c->add_option("--data-dir", data_dir_, "folder of public datasets");
  };
  auto training = [&](CLI::App* c, const std::string& types_help) {
    c->add_option("--model-type", model_types_, types_help)->capture_default_str();
    c->add_option("--features", features_,
                  "feature set: auto (cir when every file has CIR diagnostics, else power), cir "
                  "(normalised for transfer), cir-raw, power (what a range carries: received "
                  "minus first-path power, first-path power, range), sagehusa")
        ->capture_default_str();
    c->add_option("--centre", centre_,
                  "environment: each file's features less their medians over that file (its "
                  "place; no label used), which carries a model to a place whose device reads "
                  "louder or quieter when the two places have a like share of NLOS ranges, and "
                  "calls most ranges NLOS where the new place's share differs (README: NLOS "
                  "identification); a filter takes the medians of the ranges it receives. "
                  "none: the features as measured")
        ->check(CLI::IsMember({"environment", "none"}))
        ->capture_default_str();
    c->add_option("--rounds", base_.rounds, "boosting rounds")
        ->check(CLI::Range(1, 10000))
        ->capture_default_str();
    c->add_option("--depth", base_.depth, "tree depth")
        ->check(CLI::Range(1, 16))
        ->capture_default_str();
    c->add_option("--eta", base_.eta, "learning rate")
        ->check(CLI::Range(1e-4, 1.0))
        ->capture_default_str();
    c->add_option("--min-child-weight", base_.min_child_weight,
                  "smallest Hessian sum in a leaf (larger: smoother trees)")
        ->check(CLI::Range(0.0, 1e6))
        ->capture_default_str();
    c->add_option("--seed", base_.seed, "random seed (row subsampling, folds, target draws)")
        ->capture_default_str();
  };

  train_ = subcommand_->add_subcommand("train", "Train a model and save it as JSON");
  data(train_, true);
  training(train_,
           "trees-density (boosted trees, the density-weighted loss), trees-logistic (plain "
           "log-loss) or logreg (logistic regression)");
  train_->add_option("--out,-o", out_, "model file (JSON)")->required();

  eval_ = subcommand_->add_subcommand(
      "eval", "Score a model: accuracy, precision, recall, F1, ROC AUC, confusion, error RMSE");
  data(eval_, true);
  eval_->add_option("--model", model_path_, "model file (JSON)")->required();

  cv_ = subcommand_->add_subcommand(
      "cv", "Cross-validate within each file: folds grouped by location (and shuffled, for "
            "contrast)");
  data(cv_, true);
  training(cv_, "comma-separated list of model types");
  cv_->add_option("--folds", folds_, "number of folds")
      ->check(CLI::Range(2, 100))
      ->capture_default_str();

  cross_ = subcommand_->add_subcommand(
      "cross", "Across environments: train on all files but one, test on the one left out, "
               "zero-shot and with k target rows added to training");
  data(cross_, true);
  training(cross_, "comma-separated list of model types");
  cross_->add_option("--k", shots_, "target rows added to training (comma-separated)")
      ->delimiter(',')
      ->check(CLI::Range(0, 1000000))
      ->capture_default_str();
  cross_->add_option("--target-weight", target_weight_,
                     "weight of each target row; 0: the source rows' count over k (the k rows "
                     "weigh as much as the source)")
      ->check(CLI::Range(0.0, 1e9))
      ->capture_default_str();
  cross_->add_option("--repeats", repeats_, "target draws per k > 0 (their judgements pooled)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
}

int NlosCommand::run() {
  const std::string dir = data::resolveDataDir(data_dir_);
  std::vector<nlos::Table> tables;
  bool all_cir = true;
  for (const auto& f : files_) {
    tables.push_back(nlos::readLabelledRanges(data::resolveInputPath(f, dir)));
    const auto& t = tables.back();
    long nlos_rows = 0;
    for (const auto& s : t.rows) nlos_rows += s.label == 1, all_cir &= std::isfinite(s.fp_ampl1);
    std::cerr << baseName(t.source) << ": " << t.rows.size() << " rows (" << nlos_rows
              << " NLOS)";
    if (t.skipped) std::cerr << ", " << t.skipped << " without a label skipped";
    std::cerr << "\n";
    for (const auto& n : t.notes) std::cerr << "  " << n << "\n";
  }
  if (eval_->parsed()) {
    const auto model = nlos::Model::load(model_path_);
    std::cout << "model: " << model_path_ << " (" << nlos::toString(model.set) << ", "
              << model.objective << (model.centred ? ", centred on each file's medians" : "")
              << ")\n";
    if (model.centred)
      for (auto& t : tables) nlos::centreOnEnvironment(t, model.set);
    printHeader();
    for (const auto& t : tables) printScores(baseName(t.source), "loaded", nlos::score(model, nlos::pointers(t)));
    return kSuccess;
  }
  base_.set = features_ == "auto" ? (all_cir ? nlos::FeatureSet::kCir : nlos::FeatureSet::kPower)
                                  : nlos::parseFeatureSet(features_);
  if (centre_ == "environment")
    for (auto& t : tables) nlos::centreOnEnvironment(t, base_.set);
  std::vector<ModelChoice> choices;
  for (const auto& name : splitList(model_types_)) choices.push_back(modelChoice(name, base_));
  if (choices.empty()) throw nlos::DataError("--model-type: no model type given");

  if (train_->parsed()) {
    if (choices.size() != 1) throw nlos::DataError("train: give one --model-type");
    std::vector<const nlos::Sample*> rows;
    std::vector<std::string> sources;
    for (const auto& t : tables) {
      const auto p = nlos::pointers(t);
      rows.insert(rows.end(), p.begin(), p.end());
      sources.push_back(baseName(t.source));
    }
    auto model = nlos::train(rows, choices[0].params);
    model.trained_on = sources;
    model.save(out_);
    std::cout << "Trained " << choices[0].name << " on " << rows.size() << " rows ("
              << nlos::toString(model.set) << " features"
              << (model.centred ? ", centred on each file's medians" : "") << "): " << out_ << "\n";
    printHeader();
    printScores("training rows (optimistic)", choices[0].name, nlos::score(model, rows));
    return kSuccess;
  }
  std::cout << "features: " << nlos::toString(base_.set)
            << (centre_ == "environment" ? ", centred on each file's medians" : "") << "\n";
  printHeader();
  if (cv_->parsed()) {
    for (const auto& t : tables)
      for (const auto& c : choices) {
        const auto rows = nlos::pointers(t);
        printScores(baseName(t.source) + " grouped " + std::to_string(folds_) + "-fold", c.name,
                    nlos::crossValidate(rows, folds_, c.params));
        printScores(baseName(t.source) + " shuffled " + std::to_string(folds_) + "-fold", c.name,
                    nlos::crossValidate(rows, folds_, c.params, true));
      }
    return kSuccess;
  }
  // cross
  if (tables.size() < 2) throw nlos::DataError("cross: give at least two --data files");
  for (size_t held = 0; held < tables.size(); ++held) {
    std::vector<const nlos::Sample*> source;
    for (size_t i = 0; i < tables.size(); ++i)
      if (i != held) {
        const auto p = nlos::pointers(tables[i]);
        source.insert(source.end(), p.begin(), p.end());
      }
    const auto target = nlos::pointers(tables[held]);
    for (int k : shots_)
      for (const auto& c : choices) {
        std::vector<nlos::Judged> draws;
        const int n = k == 0 ? 1 : repeats_;
        for (int r = 0; r < n; ++r) {
          const auto j = nlos::transfer(source, target, k, c.params, base_.seed + r, target_weight_);
          draws.insert(draws.end(), j.begin(), j.end());
        }
        printScores("-> " + baseName(tables[held].source) + " k=" + std::to_string(k), c.name,
                    nlos::score(draws));
      }
  }
  return kSuccess;
}

}  // namespace uwbloc::apps
