#include "uwbloc/nlos/train.hpp"

#include <xgboost/c_api.h>

#include <Eigen/Dense>
#include <algorithm>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>

namespace uwbloc::nlos {
namespace {

void check(int rc, const char* what) {
  if (rc != 0) throw DataError(std::string("XGBoost: ") + what + ": " + XGBGetLastError());
}

struct Matrix {
  std::vector<float> data;  // row-major, NaN = missing
  size_t rows = 0, cols = 0;
};

Matrix featureMatrix(const std::vector<const Sample*>& rows, FeatureSet set) {
  Matrix m;
  m.rows = rows.size();
  m.cols = featureNames(set).size();
  m.data.reserve(m.rows * m.cols);
  for (const Sample* s : rows) {
    const FeatureVector x = features(set, *s);
    for (size_t j = 0; j < m.cols; ++j) m.data.push_back(static_cast<float>(x[j]));
  }
  return m;
}

// RAII owners of the C API's handles.
struct DMatrix {
  DMatrixHandle h = nullptr;
  explicit DMatrix(const Matrix& m) {
    check(XGDMatrixCreateFromMat(m.data.data(), m.rows, m.cols, NAN, &h), "DMatrix");
  }
  ~DMatrix() { XGDMatrixFree(h); }
  DMatrix(const DMatrix&) = delete;
  DMatrix& operator=(const DMatrix&) = delete;
  void set(const char* field, const std::vector<float>& v) {
    check(XGDMatrixSetFloatInfo(h, field, v.data(), v.size()), field);
  }
};
struct Booster {
  BoosterHandle h = nullptr;
  explicit Booster(DMatrix& d) { check(XGBoosterCreate(&d.h, 1, &h), "booster"); }
  ~Booster() { XGBoosterFree(h); }
  Booster(const Booster&) = delete;
  Booster& operator=(const Booster&) = delete;
  void param(const char* k, const std::string& v) {
    check(XGBoosterSetParam(h, k, v.c_str()), k);
  }
  std::vector<float> margins(DMatrix& d, bool training) {
    bst_ulong n = 0;
    const float* out = nullptr;
    check(XGBoosterPredict(h, d.h, 1, 0, training ? 1 : 0, &n, &out), "predict");
    return {out, out + n};
  }
};

// One XGBoost tree (saved-model JSON arrays) into flat nodes numbered in depth-first order, so
// that every child follows its parent.
Tree flatten(const nlohmann::json& jt) {
  const auto left = jt.at("left_children").get<std::vector<int>>();
  const auto right = jt.at("right_children").get<std::vector<int>>();
  const auto index = jt.at("split_indices").get<std::vector<int>>();
  const auto cond = jt.at("split_conditions").get<std::vector<float>>();
  const auto dleft = jt.at("default_left").get<std::vector<int>>();
  Tree t;
  std::vector<std::pair<int, int>> stack{{0, -1}};  // (xgboost node, parent slot to patch)
  std::vector<int> slot_of(left.size(), -1);
  // Preorder: visit, then left, then right.
  std::vector<int> order;
  std::vector<int> todo{0};
  while (!todo.empty()) {
    const int n = todo.back();
    todo.pop_back();
    slot_of[static_cast<size_t>(n)] = static_cast<int>(order.size());
    order.push_back(n);
    if (left[static_cast<size_t>(n)] >= 0) {
      todo.push_back(right[static_cast<size_t>(n)]);
      todo.push_back(left[static_cast<size_t>(n)]);
    }
  }
  for (int n : order) {
    const auto u = static_cast<size_t>(n);
    const bool leaf = left[u] < 0;
    t.feature.push_back(leaf ? -1 : index[u]);
    t.threshold.push_back(leaf ? 0.0f : cond[u]);
    t.value.push_back(leaf ? cond[u] : 0.0);
    const int l = leaf ? 0 : slot_of[static_cast<size_t>(left[u])];
    const int r = leaf ? 0 : slot_of[static_cast<size_t>(right[u])];
    t.yes.push_back(l);
    t.no.push_back(r);
    t.missing.push_back(leaf ? 0 : (dleft[u] ? l : r));
  }
  return t;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// 1.4826 x the median absolute deviation: the std of the bulk, blind to outliers.
double robustStd(const std::vector<double>& v) {
  const double m = median(v);
  std::vector<double> dev;
  dev.reserve(v.size());
  for (double x : v) dev.push_back(std::abs(x - m));
  return 1.4826 * median(dev);
}

// Grows `rounds` trees on (m, target) and returns them as an Additive whose offset reproduces
// XGBoost's own margins. `objective` is an XGBoost objective, or "density" (custom, see header).
Additive boost(const Matrix& m, const std::vector<float>& target, const std::vector<float>& w,
               const std::string& objective, const std::vector<double>& density_weight,
               const TrainParams& p) {
  DMatrix d(m);
  d.set("label", target);
  if (!w.empty()) d.set("weight", w);
  Booster b(d);
  b.param("objective", objective == "density" ? "binary:logitraw" : objective);
  if (objective == "reg:pseudohubererror") {
    // The error regressor: pseudo-Huber, quadratic within 1.345 robust std of the errors (95 %
    // efficiency on Gaussian errors), linear beyond, so that a few ranges metres off (multipath,
    // a reference glitch) do not drag the expectation for all; started at the median error.
    const std::vector<double> t(target.begin(), target.end());
    const double slope = std::max(1.345 * robustStd(t), 0.01);
    const double mid = median(t);
    b.param("huber_slope", std::to_string(slope));
    b.param("base_score", std::to_string(mid));
    // The pseudo-Huber Hessian vanishes far out, and a Newton leaf step g/h then explodes
    // (heavily weighted rows made the expectation metres long): no leaf moves by more than the
    // errors' own reach, the 99th percentile of |error - median|.
    std::vector<double> reach;
    for (double v : t) reach.push_back(std::abs(v - mid));
    std::nth_element(reach.begin(), reach.begin() + static_cast<long>(0.99 * (reach.size() - 1)),
                     reach.end());
    b.param("max_delta_step",
            std::to_string(std::max(reach[static_cast<size_t>(0.99 * (reach.size() - 1))], slope)));
  } else {
    b.param("base_score", "0.5");
  }
  b.param("max_depth", std::to_string(p.depth));
  b.param("eta", std::to_string(p.eta));
  b.param("subsample", std::to_string(p.subsample));
  b.param("min_child_weight", std::to_string(p.min_child_weight));
  b.param("tree_method", "hist");
  b.param("seed", std::to_string(p.seed % 2147483647));
  b.param("nthread", std::to_string(p.threads));
  b.param("verbosity", "0");
  std::vector<float> grad(m.rows), hess(m.rows);
  for (int it = 0; it < p.rounds; ++it) {
    if (objective != "density") {
      check(XGBoosterUpdateOneIter(b.h, it, d.h), "update");
      continue;
    }
    const auto margin = b.margins(d, true);
    for (size_t i = 0; i < m.rows; ++i) {
      const double prob = 1.0 / (1.0 + std::exp(-static_cast<double>(margin[i])));
      const double wi = density_weight[i] * (w.empty() ? 1.0 : w[i]);
      grad[i] = static_cast<float>(wi * (prob - target[i]));
      hess[i] = static_cast<float>(std::max(wi * prob * (1.0 - prob), 1e-6));
    }
    check(XGBoosterBoostOneIter(b.h, d.h, grad.data(), hess.data(), m.rows), "boost");
  }

  bst_ulong len = 0;
  const char* buf = nullptr;
  check(XGBoosterSaveModelToBuffer(b.h, R"({"format": "json"})", &len, &buf), "save");
  const auto j = nlohmann::json::parse(std::string(buf, len));
  Additive a;
  for (const auto& jt : j.at("learner").at("gradient_booster").at("model").at("trees"))
    a.trees.push_back(flatten(jt));

  // The offset (base score in margin space) from XGBoost's own prediction of the first row;
  // every row must then agree, which checks the export.
  const auto margin = b.margins(d, false);
  auto treeSum = [&](size_t i) {
    FeatureVector x;
    x.fill(NAN);
    for (size_t c = 0; c < m.cols; ++c) x[c] = m.data[i * m.cols + c];
    double s = 0.0;
    for (const auto& t : a.trees) s += t.evaluate(x);
    return s;
  };
  a.offset = margin[0] - treeSum(0);
  for (size_t i = 0; i < m.rows; i += std::max<size_t>(1, m.rows / 200))
    if (std::abs(a.offset + treeSum(i) - margin[i]) > 1e-3 * (1.0 + std::abs(margin[i])))
      throw DataError("XGBoost: the exported trees disagree with the booster's prediction");
  return a;
}

// Naive-Bayes Gaussian posterior per row -> the density weight 1 + 2 min(q, 1 - q).
std::vector<double> densityWeights(const Matrix& m, const std::vector<float>& y) {
  const size_t c = m.cols;
  double mu[2][kMaxFeatures] = {}, var[2][kMaxFeatures] = {}, cnt[2][kMaxFeatures] = {};
  double prior[2] = {1e-9, 1e-9};
  for (size_t i = 0; i < m.rows; ++i) {
    const int k = y[i] > 0.5f;
    prior[k] += 1.0;
    for (size_t j = 0; j < c; ++j) {
      const double v = m.data[i * c + j];
      if (std::isnan(v)) continue;
      cnt[k][j] += 1.0, mu[k][j] += v, var[k][j] += v * v;
    }
  }
  for (int k = 0; k < 2; ++k)
    for (size_t j = 0; j < c; ++j) {
      const double n = std::max(cnt[k][j], 1.0);
      mu[k][j] /= n;
      var[k][j] = std::max(var[k][j] / n - mu[k][j] * mu[k][j], 1e-9);
    }
  std::vector<double> w(m.rows);
  for (size_t i = 0; i < m.rows; ++i) {
    double ll[2] = {std::log(prior[0]), std::log(prior[1])};
    for (int k = 0; k < 2; ++k)
      for (size_t j = 0; j < c; ++j) {
        const double v = m.data[i * c + j];
        if (std::isnan(v) || cnt[0][j] < 2 || cnt[1][j] < 2) continue;
        ll[k] -= 0.5 * ((v - mu[k][j]) * (v - mu[k][j]) / var[k][j] + std::log(var[k][j]));
      }
    const double q = 1.0 / (1.0 + std::exp(std::clamp(ll[0] - ll[1], -40.0, 40.0)));
    w[i] = 1.0 + 2.0 * std::min(q, 1.0 - q);
  }
  return w;
}

// Standardised design matrix (NaN -> 0, the mean) with a leading column of ones.
Eigen::MatrixXd design(const Matrix& m, std::vector<double>& mean, std::vector<double>& scale) {
  const size_t c = m.cols;
  if (mean.empty()) {
    mean.assign(c, 0.0);
    scale.assign(c, 1.0);
    for (size_t j = 0; j < c; ++j) {
      double s = 0, s2 = 0, n = 0;
      for (size_t i = 0; i < m.rows; ++i)
        if (const double v = m.data[i * c + j]; !std::isnan(v)) s += v, s2 += v * v, n += 1;
      if (n > 0) mean[j] = s / n;
      const double sd = n > 1 ? std::sqrt(std::max(s2 / n - mean[j] * mean[j], 0.0)) : 0.0;
      scale[j] = sd > 1e-12 ? sd : 1.0;
    }
  }
  Eigen::MatrixXd x(static_cast<long>(m.rows), static_cast<long>(c + 1));
  for (size_t i = 0; i < m.rows; ++i) {
    x(static_cast<long>(i), 0) = 1.0;
    for (size_t j = 0; j < c; ++j) {
      const double v = m.data[i * c + j];
      x(static_cast<long>(i), static_cast<long>(j + 1)) =
          std::isnan(v) ? 0.0 : (v - mean[j]) / scale[j];
    }
  }
  return x;
}

// Logistic regression by Newton's method (IRLS), ridge lambda on the non-intercept weights.
Eigen::VectorXd irls(const Eigen::MatrixXd& x, const Eigen::VectorXd& y, const Eigen::VectorXd& w) {
  const long k = x.cols();
  Eigen::VectorXd beta = Eigen::VectorXd::Zero(k);
  Eigen::MatrixXd ridge = Eigen::MatrixXd::Identity(k, k) * 1e-2;
  ridge(0, 0) = 0.0;
  for (int it = 0; it < 50; ++it) {
    const Eigen::VectorXd eta = x * beta;
    Eigen::VectorXd p(eta.size()), s(eta.size());
    for (long i = 0; i < eta.size(); ++i) {
      p(i) = 1.0 / (1.0 + std::exp(-std::clamp(eta(i), -40.0, 40.0)));
      s(i) = w(i) * std::max(p(i) * (1.0 - p(i)), 1e-9);
    }
    const Eigen::MatrixXd h = x.transpose() * s.asDiagonal() * x + ridge;
    const Eigen::VectorXd g = x.transpose() * (w.cwiseProduct(y - p)) - ridge * beta;
    const Eigen::VectorXd step = h.ldlt().solve(g);
    beta += step;
    if (step.norm() < 1e-8) break;
  }
  return beta;
}

Additive linear(const Eigen::VectorXd& beta, const std::vector<double>& mean,
                const std::vector<double>& scale) {
  Additive a;
  a.offset = beta(0);
  a.weights.assign(beta.data() + 1, beta.data() + beta.size());
  a.mean = mean;
  a.scale = scale;
  return a;
}

}  // namespace

std::vector<const Sample*> pointers(const Table& t) {
  std::vector<const Sample*> out;
  out.reserve(t.rows.size());
  for (const auto& s : t.rows) out.push_back(&s);
  return out;
}

Model train(const std::vector<const Sample*>& rows, const TrainParams& params,
            const std::vector<double>& weights) {
  if (rows.empty()) throw DataError("no rows to train on");
  if (!weights.empty() && weights.size() != rows.size())
    throw DataError("one weight per training row is needed");
  long positives = 0;
  const bool centred = rows.front()->centre != nullptr;
  for (const Sample* s : rows) {
    if (s->label != 0 && s->label != 1) throw DataError("a training row has no LOS/NLOS label");
    if ((s->centre != nullptr) != centred)
      throw DataError("training rows mix features centred on their environment with raw ones");
    positives += s->label;
  }
  if (positives == 0 || positives == static_cast<long>(rows.size()))
    throw DataError("training needs both LOS and NLOS rows (got " + std::to_string(positives) +
                    " NLOS of " + std::to_string(rows.size()) + ")");

  Model model;
  model.kind = params.kind;
  model.set = params.set;
  model.centred = centred;
  model.training_rows = static_cast<long>(rows.size());
  const Matrix m = featureMatrix(rows, params.set);
  std::vector<float> y, w;
  for (const Sample* s : rows) y.push_back(static_cast<float>(s->label));
  for (double v : weights) w.push_back(static_cast<float>(v));

  // The error regressor sees the rows with a truth.
  std::vector<const Sample*> with_truth;
  std::vector<float> err, err_w;
  for (size_t i = 0; i < rows.size(); ++i)
    if (std::isfinite(rows[i]->error())) {
      with_truth.push_back(rows[i]);
      err.push_back(static_cast<float>(rows[i]->error()));
      err_w.push_back(w.empty() ? 1.0f : w[i]);
    }
  const Matrix me = featureMatrix(with_truth, params.set);

  if (params.kind == Model::Kind::kTrees) {
    if (params.objective != "density" && params.objective != "logistic")
      throw DataError("objective must be 'density' or 'logistic', not '" + params.objective + "'");
    model.objective = params.objective;
    const auto dw = params.objective == "density" ? densityWeights(m, y) : std::vector<double>{};
    model.classifier = boost(m, y, w, params.objective == "density" ? "density"
                                                                    : "binary:logistic",
                             dw, params);
    if (!with_truth.empty())
      model.regressor = boost(me, err, err_w, "reg:pseudohubererror", {}, params);
  } else {
    model.objective = "irls";
    std::vector<double> mean, scale;
    const Eigen::MatrixXd x = design(m, mean, scale);
    Eigen::VectorXd yy(static_cast<long>(y.size())), ww(static_cast<long>(y.size()));
    for (size_t i = 0; i < y.size(); ++i)
      yy(static_cast<long>(i)) = y[i], ww(static_cast<long>(i)) = w.empty() ? 1.0 : w[i];
    model.classifier = linear(irls(x, yy, ww), mean, scale);
    if (!with_truth.empty()) {
      const Eigen::MatrixXd xe = design(me, mean, scale);
      Eigen::VectorXd ye(static_cast<long>(err.size())), we(static_cast<long>(err.size()));
      for (size_t i = 0; i < err.size(); ++i)
        ye(static_cast<long>(i)) = err[i], we(static_cast<long>(i)) = err_w[i];
      // Huber regression by reweighted ridge least squares (the same 1.345 robust std as the
      // trees' pseudo-Huber slope).
      Eigen::MatrixXd ridge = Eigen::MatrixXd::Identity(xe.cols(), xe.cols()) * 1e-2;
      ridge(0, 0) = 0.0;
      const double delta =
          std::max(1.345 * robustStd(std::vector<double>(ye.data(), ye.data() + ye.size())), 0.01);
      Eigen::VectorXd beta = Eigen::VectorXd::Zero(xe.cols()), hw = we;
      for (int it = 0; it < 20; ++it) {
        const Eigen::VectorXd next = (xe.transpose() * hw.asDiagonal() * xe + ridge)
                                         .ldlt()
                                         .solve(xe.transpose() * hw.cwiseProduct(ye));
        const bool settled = (next - beta).norm() < 1e-9;
        beta = next;
        if (settled) break;
        const Eigen::VectorXd r = ye - xe * beta;
        for (long i = 0; i < r.size(); ++i)
          hw(i) = we(i) * std::min(1.0, delta / std::max(std::abs(r(i)), 1e-12));
      }
      model.regressor = linear(beta, mean, scale);
    }
  }

  // The regressor's residual std by class, on the training rows, robust (the bulk's spread: the
  // filters' own gates deal with the rest).
  std::vector<double> residuals[2];
  for (const Sample* s : with_truth) residuals[s->label].push_back(s->error() - model.judge(*s).error);
  model.sigma_los = residuals[0].size() > 1 ? std::max(robustStd(residuals[0]), 0.01) : 0.1;
  model.sigma_nlos = residuals[1].size() > 1 ? std::max(robustStd(residuals[1]), 0.01) : 0.3;
  return model;
}

Scores score(const Model& model, const std::vector<const Sample*>& rows) {
  std::vector<Judged> judged;
  judged.reserve(rows.size());
  for (const Sample* r : rows) judged.push_back({r, model.judge(*r)});
  return score(judged);
}

Scores score(const std::vector<Judged>& judged) {
  Scores s;
  std::vector<std::pair<double, int>> ranked;
  double se_b = 0, se_a = 0, nse_b = 0, nse_a = 0;
  for (const auto& [r, j] : judged) {
    if (r->label != 0 && r->label != 1) continue;
    ranked.emplace_back(j.p_nlos, r->label);
    const bool says = j.p_nlos >= 0.5;
    ++s.n;
    if (says && r->label) ++s.tp;
    if (says && !r->label) ++s.fp;
    if (!says && !r->label) ++s.tn;
    if (!says && r->label) ++s.fn;
    const double e = r->error();
    if (!std::isfinite(e)) continue;
    const double after = e - j.error;
    ++s.error_rows, se_b += e * e, se_a += after * after;
    if (r->label) ++s.nlos_error_rows, nse_b += e * e, nse_a += after * after;
  }
  auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
  s.accuracy = ratio(s.tp + s.tn, s.n);
  s.precision = ratio(s.tp, s.tp + s.fp);
  s.recall = ratio(s.tp, s.tp + s.fn);
  s.f1 = ratio(2.0 * s.precision * s.recall, s.precision + s.recall);
  s.rmse_before = std::sqrt(ratio(se_b, s.error_rows));
  s.rmse_after = std::sqrt(ratio(se_a, s.error_rows));
  s.nlos_rmse_before = std::sqrt(ratio(nse_b, s.nlos_error_rows));
  s.nlos_rmse_after = std::sqrt(ratio(nse_a, s.nlos_error_rows));
  // ROC AUC by the rank sum (ties share their mean rank).
  std::sort(ranked.begin(), ranked.end());
  double rank_sum = 0;
  long pos = 0;
  for (size_t i = 0; i < ranked.size();) {
    size_t k = i;
    while (k < ranked.size() && ranked[k].first == ranked[i].first) ++k;
    const double mean_rank = 0.5 * static_cast<double>(i + 1 + k);
    for (size_t q = i; q < k; ++q)
      if (ranked[q].second) rank_sum += mean_rank, ++pos;
    i = k;
  }
  const long neg = static_cast<long>(ranked.size()) - pos;
  s.auc = pos && neg ? (rank_sum - 0.5 * static_cast<double>(pos) * static_cast<double>(pos + 1)) /
                           (static_cast<double>(pos) * static_cast<double>(neg))
                     : NAN;
  return s;
}

std::vector<int> groupedFolds(const std::vector<const Sample*>& rows, int folds, uint64_t seed) {
  std::map<std::string, long> size;
  for (const Sample* s : rows) ++size[s->group];
  if (static_cast<int>(size.size()) < folds)
    throw DataError("grouped folds: " + std::to_string(size.size()) + " groups for " +
                    std::to_string(folds) + " folds");
  std::vector<std::pair<std::string, long>> groups(size.begin(), size.end());
  std::mt19937_64 rng(seed);
  std::shuffle(groups.begin(), groups.end(), rng);
  std::stable_sort(groups.begin(), groups.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  std::vector<long> fill(static_cast<size_t>(folds), 0);
  std::map<std::string, int> fold_of;
  for (const auto& [g, n] : groups) {
    const auto k = static_cast<size_t>(std::min_element(fill.begin(), fill.end()) - fill.begin());
    fold_of[g] = static_cast<int>(k);
    fill[k] += n;
  }
  std::vector<int> out;
  out.reserve(rows.size());
  for (const Sample* s : rows) out.push_back(fold_of[s->group]);
  return out;
}

}  // namespace uwbloc::nlos

namespace uwbloc::nlos {

Scores crossValidate(const std::vector<const Sample*>& rows, int folds, const TrainParams& params,
                     bool shuffled) {
  std::vector<int> fold;
  if (shuffled) {
    std::mt19937_64 rng(params.seed);
    fold.resize(rows.size());
    for (size_t i = 0; i < rows.size(); ++i) fold[i] = static_cast<int>(i % static_cast<size_t>(folds));
    std::shuffle(fold.begin(), fold.end(), rng);
  } else {
    fold = groupedFolds(rows, folds, params.seed);
  }
  std::vector<Judged> judged;
  for (int k = 0; k < folds; ++k) {
    std::vector<const Sample*> tr, te;
    for (size_t i = 0; i < rows.size(); ++i) (fold[i] == k ? te : tr).push_back(rows[i]);
    if (te.empty()) continue;
    const Model m = train(tr, params);
    for (const Sample* s : te) judged.push_back({s, m.judge(*s)});
  }
  return score(judged);
}

std::vector<Judged> transfer(const std::vector<const Sample*>& source,
                             const std::vector<const Sample*>& target, int k,
                             const TrainParams& params, uint64_t seed, double target_weight) {
  if (k < 0 || static_cast<size_t>(k) >= target.size())
    throw DataError("transfer: k = " + std::to_string(k) + " target rows of " +
                    std::to_string(target.size()));
  std::vector<size_t> order(target.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::mt19937_64 rng(seed);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<const Sample*> tr = source, te;
  std::vector<double> w(source.size(), 1.0);
  const double wt = target_weight > 0.0 ? target_weight
                    : k > 0 ? std::max(1.0, static_cast<double>(source.size()) / k)
                            : 1.0;
  for (size_t i = 0; i < order.size(); ++i) {
    if (static_cast<int>(i) < k) {
      tr.push_back(target[order[i]]);
      w.push_back(wt);
    } else {
      te.push_back(target[order[i]]);
    }
  }
  TrainParams p = params;
  p.seed = seed;
  const Model m = train(tr, p, w);
  std::vector<Judged> judged;
  for (const Sample* s : te) judged.push_back({s, m.judge(*s)});
  return judged;
}

}  // namespace uwbloc::nlos
