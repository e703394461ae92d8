#include "uwbloc/localization/graph/marginals.hpp"

#include <ceres/ceres.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <map>

namespace uwbloc::loc::graph {

namespace {

using Sparse = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;

// Z = (L D L^T)^-1 on the pattern of L (strictly lower part, column-major) and its diagonal.
class SelectedInverse {
 public:
  // Returns false when a needed entry lies outside L's pattern (it cannot, for a pattern from a
  // symbolic factorisation; checked rather than assumed).
  bool compute(const Sparse& l, const Eigen::VectorXd& d) {
    l_ = &l;
    const int n = static_cast<int>(l.cols());
    lower_.assign(static_cast<size_t>(l.nonZeros()), 0.0);
    diag_.assign(static_cast<size_t>(n), 0.0);
    std::vector<double> z_col;
    for (int j = n - 1; j >= 0; --j) {
      int begin = l.outerIndexPtr()[j];
      const int end = l.outerIndexPtr()[j + 1];
      z_col.assign(static_cast<size_t>(end - begin), 0.0);
      // The rows below the diagonal (the unit diagonal is not stored, but is skipped if it is).
      const int* rows = l.innerIndexPtr();
      begin = static_cast<int>(std::upper_bound(rows + begin, rows + end, j) - rows);
      for (int a = begin; a < end; ++a) {
        const int i = l.innerIndexPtr()[a];
        double sum = 0.0;
        for (int b = begin; b < end; ++b) {
          const auto z = entry(i, l.innerIndexPtr()[b]);
          if (!z) return false;
          sum += *z * l.valuePtr()[b];
        }
        z_col[static_cast<size_t>(a - begin)] = -sum;
      }
      double diag = 1.0 / d[j];
      for (int a = begin; a < end; ++a) {
        lower_[static_cast<size_t>(a)] = z_col[static_cast<size_t>(a - begin)];
        diag -= l.valuePtr()[a] * z_col[static_cast<size_t>(a - begin)];
      }
      diag_[static_cast<size_t>(j)] = diag;
    }
    return true;
  }

  // Z_ik for two indices both after the column being computed (so already known).
  std::optional<double> entry(int i, int k) const {
    if (i == k) return diag_[static_cast<size_t>(i)];
    if (i < k) std::swap(i, k);
    const int* rows = l_->innerIndexPtr();
    const int begin = l_->outerIndexPtr()[k], end = l_->outerIndexPtr()[k + 1];
    const int* at = std::lower_bound(rows + begin, rows + end, i);
    if (at == rows + end || *at != i) return std::nullopt;
    return lower_[static_cast<size_t>(at - rows)];
  }

 private:
  const Sparse* l_ = nullptr;
  std::vector<double> lower_, diag_;
};

}  // namespace

std::optional<std::vector<Eigen::MatrixXd>> marginalCovariances(
    ceres::Problem& problem, const std::vector<double*>& blocks) {
  // Columns: the wanted blocks first, in their order (poses in time order keep the factor
  // banded), then every other free block (anchors, biases, landmarks), so that the blocks that
  // couple to many poses come last and fill only the last rows.
  std::vector<double*> all, order;
  problem.GetParameterBlocks(&all);
  std::map<const double*, int> offset;
  int columns = 0;
  auto place = [&](double* b) {
    if (problem.IsParameterBlockConstant(b) || offset.count(b)) return;
    offset[b] = columns;
    columns += problem.ParameterBlockTangentSize(b);
    order.push_back(b);
  };
  for (double* b : blocks) place(b);
  for (double* b : all) place(b);
  if (columns == 0) return std::vector<Eigen::MatrixXd>{};
  ceres::Problem::EvaluateOptions eval;
  eval.parameter_blocks = order;
  eval.apply_loss_function = true;
  ceres::CRSMatrix crs;
  if (!problem.Evaluate(eval, nullptr, nullptr, nullptr, &crs)) return std::nullopt;
  Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor, int>> jacobian(
      crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()), crs.rows.data(),
      crs.cols.data(), crs.values.data());
  // Each wanted block's whole lower triangle is made part of the pattern (explicit zeros where
  // J^T J has none), so that its entries are in the factor's pattern and get computed.
  std::vector<Eigen::Triplet<double>> wanted;
  for (double* b : blocks) {
    if (!offset.count(b)) return std::nullopt;  // held constant, or not in the problem
    const int o = offset.at(b), size = problem.ParameterBlockTangentSize(b);
    for (int s = 0; s < size; ++s)
      for (int r = s; r < size; ++r) wanted.emplace_back(o + r, o + s, 0.0);
  }
  Sparse pattern(columns, columns);
  pattern.setFromTriplets(wanted.begin(), wanted.end());
  const Sparse jt = jacobian.transpose();
  const Sparse information = Sparse(jt * jacobian).triangularView<Eigen::Lower>() + pattern;
  Eigen::SimplicialLDLT<Sparse, Eigen::Lower, Eigen::NaturalOrdering<int>> ldlt(information);
  if (ldlt.info() != Eigen::Success) return std::nullopt;
  const Eigen::VectorXd d = ldlt.vectorD();
  if (!(d.minCoeff() > 0.0) || !d.allFinite()) return std::nullopt;
  const Sparse l = ldlt.matrixL().nestedExpression();
  SelectedInverse z;
  if (!z.compute(l, d)) return std::nullopt;
  std::vector<Eigen::MatrixXd> out;
  out.reserve(blocks.size());
  for (double* b : blocks) {
    const int o = offset.at(b), size = problem.ParameterBlockTangentSize(b);
    Eigen::MatrixXd c(size, size);
    for (int r = 0; r < size; ++r)
      for (int s = 0; s < size; ++s) {
        const auto v = z.entry(o + r, o + s);
        if (!v) return std::nullopt;
        c(r, s) = *v;
      }
    out.push_back(c);
  }
  return out;
}

}  // namespace uwbloc::loc::graph
