// uwb-ls, uwb-gn, uwb-chan: one multilateration fix per epoch of ranges.
#pragma once

#include <string>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

enum class MultilaterationSolver { kLinearLS, kGaussNewton, kChan };

struct MultilaterationParams {
  RangeFrontEndParams front;   ///< range checks and gates
  double epoch_window = 0.15;  ///< ranges within this span form one epoch [s]

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("window", epoch_window, "epoch window [s]");
  }
};

class MultilaterationEstimator : public UwbEstimator {
 public:
  MultilaterationEstimator(MultilaterationSolver solver, const MultilaterationParams& params,
                           const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> doProcess(const Event& event) override;
  std::optional<PoseEstimate> doFinish() override;

 private:
  std::optional<PoseEstimate> solveEpoch(const std::vector<AcceptedRange>& epoch);

  MultilaterationSolver solver_;
  MultilaterationParams params_;
  EpochBuffer epochs_;
  HeadingFromMotion heading_;
  std::optional<Eigen::Vector2d> last_tag_;
  double last_t_ = 0.0;
};

}  // namespace uwbloc::loc
