// uwb-ls, uwb-gn, uwb-chan: one multilateration fix per epoch of ranges.
#pragma once

#include <string>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/range_front_end.hpp"

namespace uwbloc::loc {

struct MultilaterationParams {
  RangeFrontEndParams front;  ///< range checks and gates
  RobotTags tags = RobotTags::kAuto;  ///< every tag (tagsEpoch) or the primary tag's only
  AutoDouble epoch_window;    ///< ranges within this span form one epoch [s]; auto: the data's rate
  bool continuity = true;     ///< check each fix against the tag's reach (fix_continuity.hpp)
  bool deskew = true;         ///< ranges moved to the epoch's time along the track (deskewRanges)
  RangeLearningParams learning;  ///< calib, calib_bias: the learning start (range_noise.hpp)

  template <class V>
  void visit(V&& v) {
    front.visit(v);
    v("tags", tags, kEpochTagsHelp);
    v("window", epoch_window,
      "epoch window [s], or auto (one round of ranges from the data's rate)");
    v("continuity", continuity, kContinuityHelp);
    v("deskew", deskew, kDeskewHelp);
    learning.visit(v);
  }
};

class MultilaterationEstimator : public EpochUwbEstimator {
 public:
  MultilaterationEstimator(MultilaterationSolver solver, const MultilaterationParams& params,
                           const EstimatorContext& context);

 protected:
  std::optional<PoseEstimate> onEpoch(const std::vector<AcceptedRange>& epoch) override;

 private:
  MultilaterationSolver solver_;
  MultilaterationParams params_;
  HeadingFromMotion heading_;
  std::optional<Eigen::Vector2d> last_tag_;
  double last_t_ = 0.0;
};

}  // namespace uwbloc::loc
