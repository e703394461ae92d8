// Continuity of per-epoch fixes. Among three anchors one wrong range can fit the mirror image of
// the true position exactly (the MRPT demo's beacon 1 does so for tens of seconds), so no
// residual can tell; only the motion can. A fix the tag cannot have reached since the last kept
// one (at the fastest plausible speed, with both fixes' uncertainty) is in doubt, and the reachable
// position that the most of the epoch's ranges fit is used instead, leaving the others out: fault
// exclusion by continuity.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <optional>
#include <vector>

#include "uwbloc/uwb/multilateration.hpp"

namespace uwbloc::loc {

struct FixContinuityParams {
  double max_speed = 2.0;   ///< fastest plausible tag speed [m/s]
  double floor = 0.3;       ///< distance always reachable, and a range's fit tolerance [m]
  int max_unreachable = 5;  ///< epochs in a row with nothing reachable before a restart
};

/// Why a fix was kept, changed or refused.
enum class Continuity {
  kAsIs,         ///< the fix was reachable (or the first)
  kExcluded,     ///< replaced by a reachable position that leaves some ranges out
  kUnreachable,  ///< refused: nothing the ranges allow is reachable
  kRestart,      ///< taken as it is after max_unreachable refusals in a row
};

const char* toString(Continuity c);

class FixContinuity {
 public:
  using Solver = std::function<uwb::Fix(const std::vector<uwb::PlanarRange>&)>;
  struct Checked {
    std::optional<uwb::Fix> fix;  ///< the fix to use; none when refused
    Continuity outcome = Continuity::kAsIs;
    std::vector<int> left_out;  ///< indices into the ranges that the used fix leaves out
  };

  explicit FixContinuity(const FixContinuityParams& params = {}) : params_(params) {}

  /// A known position at time t (the start pose's tag); the first fix is then checked too.
  void seed(double t, const Eigen::Vector2d& position);

  /// A speed the data showed (the learnt path's); only raises the one in force.
  void raiseMaxSpeed(double v);

  /// `fix` (status ok) from `ranges` at time t. When it is not reachable from the last kept
  /// position, each pair of ranges' circle intersections that is reachable and fits all the
  /// ranges but one at most (within max(3 sigma, floor): one fault at a time) is a candidate; the
  /// one that fits the most, then the nearest, is re-solved by `solve` over the ranges it fits
  /// (three or more) or kept as it is (two).
  ///
  /// `offset` moves the ranges' point (a tag) to the point whose continuity is checked and kept
  /// (the robot, with the lever arm rotated by a known heading: -R(theta) l); the fix returned is
  /// the ranges' point.
  Checked check(double t, const uwb::Fix& fix, const std::vector<uwb::PlanarRange>& ranges,
                const Solver& solve, const Eigen::Vector2d& offset = Eigen::Vector2d::Zero());

 private:
  /// Within floor + max_speed dt + 3 (the fix's largest std, with `own_std`, + the last kept
  /// one's) of the last kept position. A candidate is judged without its own std: a pair's
  /// intersection near the line through its anchors has a large one, and would reach anywhere.
  bool reachable(double t, const uwb::Fix& fix, bool own_std, const Eigen::Vector2d& offset) const;
  void keep(double t, const uwb::Fix& fix, const Eigen::Vector2d& offset);
  /// The best reachable candidate position, with the indices of the ranges it fits.
  struct Candidate {
    uwb::Fix fix;
    std::vector<int> in;
  };
  std::optional<Candidate> bestReachable(double t, const std::vector<uwb::PlanarRange>& ranges,
                                         const Solver& solve, const Eigen::Vector2d& offset) const;

  FixContinuityParams params_;
  std::optional<Eigen::Vector2d> last_;
  double last_t_ = 0.0;
  double last_std_ = 0.0;  ///< the last kept fix's largest std [m]
  int unreachable_ = 0;
};

}  // namespace uwbloc::loc
