#include "uwbloc/nlos/model.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace uwbloc::nlos {

namespace {
constexpr const char* kFormat = "uwbloc-nlos-model";

double snrDb(double amplitude, double noise) {
  return amplitude > 0.0 && noise > 0.0 ? 20.0 * std::log10(amplitude / noise) : NAN;
}
}  // namespace

FeatureSet parseFeatureSet(const std::string& name) {
  for (FeatureSet s :
       {FeatureSet::kCir, FeatureSet::kCirRaw, FeatureSet::kPower, FeatureSet::kSageHusa})
    if (name == toString(s)) return s;
  throw DataError("unknown feature set '" + name + "' (choose cir, cir-raw, power, sagehusa)");
}

const char* toString(FeatureSet set) {
  switch (set) {
    case FeatureSet::kCir:
      return "cir";
    case FeatureSet::kCirRaw:
      return "cir-raw";
    case FeatureSet::kPower:
      return "power";
    case FeatureSet::kSageHusa:
      return "sagehusa";
  }
  return "?";
}

const std::vector<std::string>& featureNames(FeatureSet set) {
  static const std::vector<std::string> cir = {
      "rx_minus_fp_db",   "rx_power_dbm", "fp_power_dbm", "fp_ampl1_snr_db",     "fp_ampl2_snr_db",
      "fp_ampl3_snr_db",  "pr",           "range_m",      "fp_ampl1_per_acc_db", "noise_per_acc_db",
      "fp_index_fraction"};
  static const std::vector<std::string> cir_raw = {
      "fp_ampl1", "fp_ampl2",     "fp_ampl3",     "std_noise",      "cir_power", "rxpacc",
      "fp_index", "rx_power_dbm", "fp_power_dbm", "rx_minus_fp_db", "pr",        "range_m"};
  static const std::vector<std::string> power = {"rx_minus_fp_db", "fp_power_dbm", "range_m"};
  static const std::vector<std::string> sagehusa = {"rx_minus_fp_db", "predicted_minus_range_m"};
  switch (set) {
    case FeatureSet::kCir:
      return cir;
    case FeatureSet::kCirRaw:
      return cir_raw;
    case FeatureSet::kPower:
      return power;
    case FeatureSet::kSageHusa:
      return sagehusa;
  }
  return power;
}

int featureCount(FeatureSet set) { return static_cast<int>(featureNames(set).size()); }

namespace {
// The set's features as the range was measured, whatever centre it carries.
FeatureVector measuredFeatures(FeatureSet set, const Sample& s) {
  FeatureVector x;
  x.fill(NAN);
  const double pd = s.rx_power_dbm - s.fp_power_dbm;
  switch (set) {
    case FeatureSet::kCir:
      // Amplitudes over the noise std: both scale with the preamble accumulation count, so the
      // ratio carries across devices configured with other preamble lengths.
      x = {pd,
           s.rx_power_dbm,
           s.fp_power_dbm,
           snrDb(s.fp_ampl1, s.std_noise),
           snrDb(s.fp_ampl2, s.std_noise),
           snrDb(s.fp_ampl3, s.std_noise),
           s.pr,
           s.range,
           snrDb(s.fp_ampl1, s.rxpacc),
           snrDb(s.std_noise, s.rxpacc),
           s.fp_index - std::floor(s.fp_index),
           NAN};
      break;
    case FeatureSet::kCirRaw:
      x = {s.fp_ampl1, s.fp_ampl2,     s.fp_ampl3,     s.std_noise, s.cir_power, s.rxpacc,
           s.fp_index, s.rx_power_dbm, s.fp_power_dbm, pd,          s.pr,        s.range};
      break;
    case FeatureSet::kPower:
      x[0] = pd, x[1] = s.fp_power_dbm, x[2] = s.range;
      break;
    case FeatureSet::kSageHusa:
      x[0] = pd, x[1] = s.innovation;
      break;
  }
  return x;
}
}  // namespace

FeatureVector features(FeatureSet set, const Sample& s) {
  FeatureVector x = measuredFeatures(set, s);
  if (s.centre) {
    if (s.centre->set != set)
      throw std::logic_error(std::string("a range centred for the feature set ") +
                             toString(s.centre->set) + " asked for " + toString(set));
    for (int j = 0; j < kMaxFeatures; ++j)
      if (std::isfinite(s.centre->median[static_cast<size_t>(j)]))
        x[static_cast<size_t>(j)] -= s.centre->median[static_cast<size_t>(j)];
  }
  return x;
}

EnvironmentCentre environmentCentre(FeatureSet set, const std::vector<const Sample*>& rows) {
  EnvironmentCentre c;
  c.set = set;
  c.rows = static_cast<long>(rows.size());
  const size_t n = static_cast<size_t>(featureCount(set));
  std::vector<std::vector<double>> values(n);
  for (const Sample* s : rows) {
    const FeatureVector x = measuredFeatures(set, *s);
    for (size_t j = 0; j < n; ++j)
      if (std::isfinite(x[j])) values[j].push_back(x[j]);
  }
  c.median.fill(NAN);
  for (size_t j = 0; j < n; ++j) c.median[j] = medianOfFinite(values[j]);
  return c;
}

void centreOnEnvironment(Table& t, FeatureSet set) {
  std::vector<const Sample*> rows;
  rows.reserve(t.rows.size());
  for (const auto& s : t.rows) rows.push_back(&s);
  const auto centre = std::make_shared<const EnvironmentCentre>(environmentCentre(set, rows));
  for (auto& s : t.rows) s.centre = centre;
}

RunningCentre::RunningCentre(FeatureSet set, long min_rows, long freeze_at)
    : set_(set),
      min_rows_(std::max(1L, min_rows)),
      freeze_at_(std::max(min_rows_, freeze_at)),
      next_(min_rows_),
      values_(static_cast<size_t>(featureCount(set))) {}

void RunningCentre::add(const FeatureVector& x) {
  if (seen_ >= freeze_at_) return;
  ++seen_;
  for (size_t j = 0; j < values_.size(); ++j)
    if (std::isfinite(x[j])) values_[j].push_back(x[j]);
  if (seen_ < next_ && seen_ < freeze_at_) return;
  next_ *= 2;
  auto c = std::make_shared<EnvironmentCentre>();
  c->set = set_;
  c->rows = seen_;
  c->median.fill(NAN);
  // A median does not care about the order of what it is taken over: in place.
  for (size_t j = 0; j < values_.size(); ++j) c->median[j] = medianOfFinite(values_[j]);
  centre_ = std::move(c);
  if (seen_ >= freeze_at_) values_.clear();
}

Judgement Model::judge(const Sample& s) const {
  if (centred && !s.centre)
    throw DataError(
        "the NLOS model was trained on features centred on their environment's "
        "medians; this range carries no centre");
  return judge(features(set, s));
}

Sample sampleOf(const uwb::Range& r, double innovation) {
  Sample s;
  s.range = r.range;
  s.rx_power_dbm = r.rx_power_dbm.value_or(NAN);
  s.fp_power_dbm = r.fp_power_dbm.value_or(NAN);
  s.innovation = innovation;
  return s;
}

double Tree::evaluate(const FeatureVector& x) const {
  int i = 0;
  for (size_t guard = 0; guard < feature.size(); ++guard) {
    const int f = feature[static_cast<size_t>(i)];
    if (f < 0) return value[static_cast<size_t>(i)];
    const double v = x[static_cast<size_t>(f)];
    // XGBoost compares in single precision.
    i = std::isnan(v) ? missing[static_cast<size_t>(i)]
        : static_cast<float>(v) < threshold[static_cast<size_t>(i)] ? yes[static_cast<size_t>(i)]
                                                                    : no[static_cast<size_t>(i)];
  }
  return 0.0;  // unreachable for a well-formed tree (fromJson checks the links)
}

double Additive::evaluate(const FeatureVector& x, int n_features) const {
  double m = offset;
  for (const auto& t : trees) m += t.evaluate(x);
  for (size_t j = 0; j < weights.size() && static_cast<int>(j) < n_features; ++j) {
    const double v = std::isnan(x[j]) ? 0.0 : (x[j] - mean[j]) / scale[j];  // NaN: the mean
    m += weights[j] * v;
  }
  return m;
}

Judgement Model::judge(const FeatureVector& x) const {
  const int n = featureCount();
  Judgement j;
  double margin = classifier.evaluate(x, n);
  if (std::isnan(margin)) margin = 0.0;  // a model that overflows says nothing (P = 0.5)
  j.p_nlos = 1.0 / (1.0 + std::exp(-std::clamp(margin, -40.0, 40.0)));
  j.error = regressor.evaluate(x, n);
  if (!std::isfinite(j.error)) j.error = 0.0;
  j.error_sigma =
      std::sqrt((1.0 - j.p_nlos) * sigma_los * sigma_los + j.p_nlos * sigma_nlos * sigma_nlos);
  return j;
}

namespace {

nlohmann::json toJson(const Additive& a) {
  nlohmann::json j;
  j["offset"] = a.offset;
  if (!a.weights.empty()) {
    j["weights"] = a.weights;
    j["mean"] = a.mean;
    j["scale"] = a.scale;
  }
  auto trees = nlohmann::json::array();
  for (const auto& t : a.trees)
    trees.push_back({{"feature", t.feature},
                     {"threshold", t.threshold},
                     {"yes", t.yes},
                     {"no", t.no},
                     {"missing", t.missing},
                     {"value", t.value}});
  j["trees"] = trees;
  return j;
}

// A JSON array of numbers, each finite and within [lo, hi] (a float's or an int's range: the
// conversion of a number beyond it would be undefined).
std::vector<double> numbers(const nlohmann::json& j, const char* key, double lo, double hi,
                            const std::string& where) {
  const auto& a = j.at(key);
  if (!a.is_array()) throw DataError(where + ": '" + key + "' must be an array");
  std::vector<double> out;
  out.reserve(a.size());
  for (const auto& v : a) {
    if (!v.is_number()) throw DataError(where + ": '" + key + "' holds a non-number");
    const double x = v.get<double>();
    if (!std::isfinite(x) || x < lo || x > hi)
      throw DataError(where + ": '" + key + "' holds " + v.dump() + ", out of range");
    out.push_back(x);
  }
  return out;
}

std::vector<int> integers(const nlohmann::json& j, const char* key, const std::string& where) {
  std::vector<int> out;
  for (double x : numbers(j, key, -1e9, 1e9, where)) {
    if (x != std::floor(x)) throw DataError(where + ": '" + key + "' holds a non-integer");
    out.push_back(static_cast<int>(x));
  }
  return out;
}

Additive additiveFrom(const nlohmann::json& j, int n_features, const std::string& where) {
  Additive a;
  a.offset = j.at("offset").get<double>();
  if (!std::isfinite(a.offset)) throw DataError(where + ": 'offset' is not finite");
  if (j.contains("weights")) {
    a.weights = numbers(j, "weights", -1e300, 1e300, where);
    a.mean = numbers(j, "mean", -1e300, 1e300, where);
    a.scale = numbers(j, "scale", -1e300, 1e300, where);
    if (static_cast<int>(a.weights.size()) != n_features || a.mean.size() != a.weights.size() ||
        a.scale.size() != a.weights.size())
      throw DataError(where + ": weights, mean and scale must have one entry per feature");
    for (double s : a.scale)
      if (!(s > 0.0)) throw DataError(where + ": a scale is not positive");
  }
  for (const auto& jt : j.at("trees")) {
    Tree t;
    t.feature = integers(jt, "feature", where);
    for (double x : numbers(jt, "threshold", -3.4e38, 3.4e38, where))
      t.threshold.push_back(static_cast<float>(x));
    t.yes = integers(jt, "yes", where);
    t.no = integers(jt, "no", where);
    t.missing = integers(jt, "missing", where);
    t.value = numbers(jt, "value", -1e300, 1e300, where);
    const size_t n = t.feature.size();
    if (n == 0 || t.threshold.size() != n || t.yes.size() != n || t.no.size() != n ||
        t.missing.size() != n || t.value.size() != n)
      throw DataError(where + ": a tree's node arrays differ in length");
    // Children must come after their parent: a walk then always ends at a leaf.
    for (size_t i = 0; i < n; ++i) {
      if (t.feature[i] < 0) continue;
      if (t.feature[i] >= n_features)
        throw DataError(where + ": a tree splits on feature " + std::to_string(t.feature[i]) +
                        ", beyond the feature set");
      for (int c : {t.yes[i], t.no[i], t.missing[i]})
        if (c <= static_cast<int>(i) || c >= static_cast<int>(n))
          throw DataError(where + ": a tree's node " + std::to_string(i) +
                          " links outside the tree or backwards");
    }
    a.trees.push_back(std::move(t));
  }
  return a;
}

}  // namespace

std::string Model::toJson() const {
  nlohmann::json j;
  j["format"] = kFormat;
  j["version"] = 1;
  j["kind"] = kind == Kind::kTrees ? "trees" : "logistic";
  j["objective"] = objective;
  j["features"] = toString(set);
  j["feature_names"] = featureNames(set);
  j["classifier"] = nlos::toJson(classifier);
  j["regressor"] = nlos::toJson(regressor);
  j["error_sigma"] = {{"los", sigma_los}, {"nlos", sigma_nlos}};
  j["centred"] = centred;
  j["trained_on"] = trained_on;
  j["training_rows"] = training_rows;
  return j.dump();
}

Model Model::fromJson(const std::string& text, const std::string& source) {
  Model m;
  try {
    const auto j = nlohmann::json::parse(text);
    if (j.value("format", "") != kFormat)
      throw DataError(source + ": not an uwbloc NLOS model (field 'format' is not '" +
                      std::string(kFormat) + "')");
    const std::string kind = j.at("kind").get<std::string>();
    if (kind != "trees" && kind != "logistic")
      throw DataError(source + ": field 'kind' must be 'trees' or 'logistic'");
    m.kind = kind == "trees" ? Kind::kTrees : Kind::kLogistic;
    m.objective = j.value("objective", "");
    m.set = parseFeatureSet(j.at("features").get<std::string>());
    m.classifier = additiveFrom(j.at("classifier"), m.featureCount(), source + ": classifier");
    m.regressor = additiveFrom(j.at("regressor"), m.featureCount(), source + ": regressor");
    m.sigma_los = j.at("error_sigma").at("los").get<double>();
    m.sigma_nlos = j.at("error_sigma").at("nlos").get<double>();
    if (!(m.sigma_los > 0.0 && m.sigma_los < 1e6) || !(m.sigma_nlos > 0.0 && m.sigma_nlos < 1e6))
      throw DataError(source + ": error_sigma must be positive and finite");
    m.centred = j.value("centred", false);
    m.trained_on = j.value("trained_on", std::vector<std::string>{});
    if (j.contains("training_rows") && j.at("training_rows").is_number_integer())
      m.training_rows = j.at("training_rows").get<long>();
  } catch (const nlohmann::json::exception& e) {
    throw DataError(source + ": " + e.what());
  }
  return m;
}

void Model::save(const std::string& path) const {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) throw DataError(path + ": cannot write");
    out << toJson() << "\n";
    if (!out) throw DataError(path + ": write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) throw DataError(path + ": cannot write");
}

Model Model::load(const std::string& path) {
  requireRegularFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DataError(path + ": cannot open the NLOS model");
  std::stringstream buf;
  buf << in.rdbuf();
  return fromJson(buf.str(), path);
}

}  // namespace uwbloc::nlos
