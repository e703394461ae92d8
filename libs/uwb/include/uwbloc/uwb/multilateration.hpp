// Position from ranges to known anchors, in the plane (ranges already height-projected).
//
// Every solver returns a Fix with the same covariance model, sigma^2 (H^T H)^-1 with H the unit
// vectors from the anchors to the solution, so the solvers can be compared and gated alike.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

namespace uwbloc::uwb {

enum class FixStatus {
  kOk,
  kTooFewAnchors,  ///< fewer than 3 usable ranges
  kDegenerate,     ///< anchors (nearly) collinear or coincident: no unique 2D solution
  kNoConvergence,  ///< iterative solver did not converge
};

const char* toString(FixStatus s);

struct Fix {
  FixStatus status = FixStatus::kTooFewAnchors;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  double residual_norm = 0.0;  ///< || r_i - ||p - a_i|| ||, over the used ranges [m]
  int iterations = 0;
  bool ok() const { return status == FixStatus::kOk; }
};

/// One planar range: anchor position and projected range r_i.
struct PlanarRange {
  Eigen::Vector2d anchor;
  double range = 0.0;
  double sigma = 0.1;  ///< standard deviation [m], used for weighting and the covariance
};

/// Linearised least squares: each circle equation minus the first one gives A X = B
/// (the greenhouse paper's eq. 9-14); solved by column-pivoting QR.
Fix solveLinearLS(const std::vector<PlanarRange>& ranges);

struct GaussNewtonParams {
  int max_iterations = 20;   ///< iteration cap
  double tolerance = 1e-10;  ///< step-norm convergence threshold [m]
};

/// Weighted Gauss-Newton on r_i = ||p - a_i|| (weights 1/sigma_i^2). Starts from `initial`, or
/// from the linear LS solution when none is given.
Fix solveGaussNewton(const std::vector<PlanarRange>& ranges,
                     const std::optional<Eigen::Vector2d>& initial = std::nullopt,
                     const GaussNewtonParams& params = {});

/// Chan's two-step weighted least squares for TOA ranges: first solve linearly for
/// (x, y, R = x^2 + y^2), then refine using the relation between R and (x, y).
Fix solveChan(const std::vector<PlanarRange>& ranges);

/// Closed form for exactly three anchors: intersect the circles of the first two anchors and
/// keep the intersection that best fits the third circle. When noise keeps the first two
/// circles apart, the point on the line between their centres is used.
Fix solveThreeAnchors(const std::vector<PlanarRange>& ranges);

/// Where the circles of two planar ranges meet: two points; one, on the line between the
/// anchors, when noise keeps the circles apart (or one inside the other); none when the
/// anchors coincide.
std::vector<Eigen::Vector2d> circleIntersections(const PlanarRange& a, const PlanarRange& b);

/// A fix at a given position: its residual over `ranges` and the CRLB there as its covariance;
/// kNoConvergence when the position is not finite, kDegenerate when the bound is singular.
Fix fixAt(const std::vector<PlanarRange>& ranges, const Eigen::Vector2d& position,
          int iterations = 0);

/// Static Cramér–Rao bound of a 2D position: sigma^2 (H^T H)^-1 with unit-vector rows H (equal
/// sigma), or (H^T W H)^-1 with W = diag(1/sigma_i^2). Returns nothing when singular.
std::optional<Eigen::Matrix2d> crlb2d(const std::vector<PlanarRange>& ranges,
                                      const Eigen::Vector2d& position);

}  // namespace uwbloc::uwb
