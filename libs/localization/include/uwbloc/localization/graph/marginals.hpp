// Marginal covariances of chosen parameter blocks of a solved Ceres problem, by sparse LDL^T of
// the Gauss-Newton information J^T J and Takahashi's selected inversion (Takahashi, Fagan and
// Chen 1973; Erisman and Tinney 1975): the entries of (J^T J)^-1 are computed only where the
// factor has entries, from the last column back,
//   Z_ij = -sum_{k in S_j} Z_ik L_kj   (i in S_j),   Z_jj = 1 / D_j - sum_{k in S_j} L_kj Z_kj,
// S_j the rows below the diagonal of L's column j. A chain of poses in time order, with the few
// anchor, bias and landmark blocks last, factors with little fill, so the cost is about linear
// in the poses; ceres::Covariance solves for every requested column and grows with their square.
// Every free block of the problem takes part (the held ones are constants); the Jacobian is
// taken in each block's tangent space, with the robust losses applied, as ceres::Covariance does.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

namespace ceres {
class Problem;
}

namespace uwbloc::loc::graph {

/// The tangent-space covariance block of each of `blocks` (free parameter blocks of `problem`,
/// in any order; the others are marginalised). Nothing when J^T J is not positive definite
/// (a gauge left free, a block without measurements).
std::optional<std::vector<Eigen::MatrixXd>> marginalCovariances(ceres::Problem& problem,
                                                                const std::vector<double*>& blocks);

}  // namespace uwbloc::loc::graph
