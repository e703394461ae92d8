// Training and scoring of the NLOS models (model.hpp).
//
// Boosted trees are grown by XGBoost (Debian's libxgboost, C API) and dumped into the model's
// own node arrays. Two objectives:
//   - "logistic": the plain binary log-loss;
//   - "density": the improved Sage-Husa paper's probability-density boosting tree. Its
//     equations did not survive in our copy of the paper; what survives says that the loss
//     takes in the distribution density of the features so that the trees learn the rows where
//     the LOS and NLOS feature values meet (its Fig. 5/6). Our reading: a Gaussian density per
//     class and feature (naive Bayes) gives each training row the posterior q of its class
//     mixture, and the row's log-loss is weighted by 1 + 2 min(q, 1 - q), which is 2 where the
//     two densities are equal and 1 where one dominates. Gradient and Hessian are those of the
//     weighted log-loss, passed to XGBoost's BoostOneIter.
// The logistic-regression baseline is fitted by Newton's method (IRLS) on standardised
// features with a small ridge; its error regressor is ridge least squares.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "uwbloc/nlos/model.hpp"

namespace uwbloc::nlos {

struct TrainParams {
  Model::Kind kind = Model::Kind::kTrees;
  std::string objective = "density";  ///< trees: "density" or "logistic"
  FeatureSet set = FeatureSet::kCir;
  int rounds = 50;     ///< boosting rounds (few: more fit the training spots, not new ones)
  int depth = 3;       ///< tree depth
  double eta = 0.1;    ///< learning rate
  double subsample = 0.8;
  double min_child_weight = 5.0;
  uint64_t seed = 1;
  int threads = 2;
};

/// A model from labelled rows; `weights` (optional, one per row) weight them.
Model train(const std::vector<const Sample*>& rows, const TrainParams& params,
            const std::vector<double>& weights = {});

/// The scores of a model on labelled rows.
struct Scores {
  long n = 0, tp = 0, fp = 0, tn = 0, fn = 0;  ///< positive = NLOS, at P(NLOS) >= 0.5
  double accuracy = 0, precision = 0, recall = 0, f1 = 0, auc = 0;
  long error_rows = 0;                       ///< rows with a true range
  double rmse_before = 0, rmse_after = 0;    ///< range error, all rows with a truth [m]
  long nlos_error_rows = 0;
  double nlos_rmse_before = 0, nlos_rmse_after = 0;  ///< on the NLOS rows [m]
};
Scores score(const Model& model, const std::vector<const Sample*>& rows);
/// A row with what a model said of it.
using Judged = std::pair<const Sample*, Judgement>;
/// The scores of judged rows (the out-of-fold judgements of several models, pooled).
Scores score(const std::vector<Judged>& judged);

/// A fold index per row, with every group in one fold, the groups shuffled with `seed` and
/// dealt largest first to the smallest fold. Throws DataError with fewer groups than folds.
std::vector<int> groupedFolds(const std::vector<const Sample*>& rows, int folds, uint64_t seed);

/// Rows of a table, as pointers.
std::vector<const Sample*> pointers(const Table& t);

}  // namespace uwbloc::nlos

namespace uwbloc::nlos {

/// k-fold cross-validation, pooled over the folds: folds grouped by `Sample::group` (what a new
/// place scores), or rows shuffled (what a place already seen scores; reported for contrast).
Scores crossValidate(const std::vector<const Sample*>& rows, int folds, const TrainParams& params,
                     bool shuffled = false);

/// Transfer to a new environment: train on `source` plus `k` rows drawn (with `seed`) from
/// `target`, each weighted `target_weight` (<= 0: auto, so that the k rows together weigh as
/// much as the source), and judge the target's other rows.
std::vector<Judged> transfer(const std::vector<const Sample*>& source, const std::vector<const Sample*>& target,
                int k, const TrainParams& params, uint64_t seed, double target_weight = 0.0);

}  // namespace uwbloc::nlos
