// The NLOS model: features of one range -> P(NLOS), and the range's expected error with its
// standard deviation. Two kinds behind one interface:
//   - boosted trees, trained by XGBoost (train.hpp) and evaluated here from their own flat node
//     arrays, so that a filter needs no XGBoost at run time and a range costs a few tree walks;
//   - logistic regression (with a ridge regressor for the error), no dependency.
// A model is saved as JSON and loaded back with identical predictions.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "uwbloc/nlos/table.hpp"
#include "uwbloc/uwb/types.hpp"

namespace uwbloc::nlos {

/// The feature sets. Each is a fixed list of quantities computed from a Sample; a quantity the
/// range does not carry is NaN (the trees route it by their learnt default, the logistic model
/// takes the training mean).
enum class FeatureSet {
  kCir,       ///< "cir": the Ghent CIR set, normalised for transfer (see featureNames)
  kCirRaw,    ///< "cir-raw": the Ghent columns as the device reports them
  kPower,     ///< "power": received minus first-path power, first-path power, range
  kSageHusa,  ///< "sagehusa": received minus first-path power; predicted distance minus range
};
FeatureSet parseFeatureSet(const std::string& name);  ///< throws DataError naming the choices
const char* toString(FeatureSet set);
const std::vector<std::string>& featureNames(FeatureSet set);
/// How many features the set has.
int featureCount(FeatureSet set);

constexpr int kMaxFeatures = 12;
using FeatureVector = std::array<double, kMaxFeatures>;
/// The set's features of `s` (the first featureNames(set).size() entries are used), less the
/// sample's environment centre when it carries one (of the same set: else std::logic_error).
FeatureVector features(FeatureSet set, const Sample& s);

/// An environment's centre: the median of each feature over its ranges (labels unused, so a
/// robot can take it from the ranges it receives). Antennas, the device's calibration and the
/// preamble move the powers and amplitudes of every range in a place together, by more than
/// the LOS / NLOS difference across places: the Ghent IIoT and university files differ by
/// several dB. A model trained on features centred on their own environment's medians, and
/// fed features centred on the new place's, judges by where a range stands in its place's
/// spread, which carries across places (see README "NLOS identification").
struct EnvironmentCentre {
  FeatureSet set = FeatureSet::kPower;
  FeatureVector median{};  ///< NaN where no range carried the feature: that one stays as is
  long rows = 0;           ///< ranges it was taken over
};
/// The centre of `rows` for `set` (their own centres ignored).
EnvironmentCentre environmentCentre(FeatureSet set, const std::vector<const Sample*>& rows);
/// Points every row of `t` at the centre of its rows for `set`.
void centreOnEnvironment(Table& t, FeatureSet set);

/// An environment's centre taken on line from the ranges as they arrive: the medians of the
/// features seen so far, re-taken at 32, 64, 128, ... ranges and kept from `freeze_at` on.
class RunningCentre {
 public:
  explicit RunningCentre(FeatureSet set, long min_rows = 32, long freeze_at = 4096);
  /// Adds a range's (uncentred) features.
  void add(const FeatureVector& x);
  /// The centre once `min_rows` ranges were seen; none before.
  std::shared_ptr<const EnvironmentCentre> centre() const { return centre_; }

 private:
  FeatureSet set_;
  long min_rows_, freeze_at_, next_ = 0, seen_ = 0;
  std::vector<std::vector<double>> values_;  // per feature
  std::shared_ptr<const EnvironmentCentre> centre_;
};
/// A Sample from what a uwb::Range carries (powers and range); the innovation when given.
Sample sampleOf(const uwb::Range& r, double innovation = NAN);

/// One regression tree in flat form: node i splits on feature[i] < threshold[i] (yes) or not
/// (no), a missing value goes to missing[i]; feature[i] < 0 marks a leaf with value[i].
struct Tree {
  std::vector<int> feature, yes, no, missing;
  std::vector<float> threshold;
  std::vector<double> value;
  double evaluate(const FeatureVector& x) const;
};

/// An additive model: offset + the sum of its trees, or offset + w . standardised(x).
struct Additive {
  double offset = 0.0;
  std::vector<Tree> trees;                     ///< the trees, when boosted
  std::vector<double> weights, mean, scale;    ///< the linear part, when logistic
  double evaluate(const FeatureVector& x, int n_features) const;
};

/// What the model says about one range.
struct Judgement {
  double p_nlos = 0.0;       ///< P(NLOS)
  double error = 0.0;        ///< expected estimated - true range [m]
  double error_sigma = 0.0;  ///< std of that expectation [m]
};

class Model {
 public:
  enum class Kind { kTrees, kLogistic };

  Kind kind = Kind::kTrees;
  std::string objective;  ///< how it was trained: "density", "logistic", "irls"
  FeatureSet set = FeatureSet::kPower;
  Additive classifier;    ///< margin: P(NLOS) = 1 / (1 + exp(-margin))
  Additive regressor;     ///< expected error [m]
  double sigma_los = 0.1, sigma_nlos = 0.3;  ///< residual std of the regressor by class [m]
  /// Trained on features centred on each environment's medians (EnvironmentCentre): it judges
  /// only ranges that carry their environment's centre.
  bool centred = false;
  std::vector<std::string> trained_on;       ///< source files
  long training_rows = 0;

  Judgement judge(const FeatureVector& x) const;
  /// Throws DataError when the model is centred and `s` carries no centre.
  Judgement judge(const Sample& s) const;
  int featureCount() const { return nlos::featureCount(set); }

  std::string toJson() const;
  static Model fromJson(const std::string& text, const std::string& source);
  void save(const std::string& path) const;
  static Model load(const std::string& path);  ///< throws DataError naming the file
};

}  // namespace uwbloc::nlos
