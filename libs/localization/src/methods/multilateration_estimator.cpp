#include "uwbloc/localization/methods/multilateration_estimator.hpp"

#include "uwbloc/localization/kalman/kalman.hpp"

namespace uwbloc::loc {

MultilaterationEstimator::MultilaterationEstimator(MultilaterationSolver solver,
                                                   const MultilaterationParams& params,
                                                   const EstimatorContext& context)
    : UwbEstimator(params.front, context.anchors),
      solver_(solver),
      params_(params),
      epochs_(params.epoch_window) {
  if (context.initial_pose) heading_.setHeading(context.initial_pose->z());
}

std::optional<PoseEstimate> MultilaterationEstimator::doProcess(const Event& event) {
  const auto accepted = acceptRange(event);
  if (!accepted) return std::nullopt;
  if (auto epoch = epochs_.add(*accepted)) return solveEpoch(*epoch);
  return std::nullopt;
}

std::optional<PoseEstimate> MultilaterationEstimator::doFinish() {
  if (auto epoch = epochs_.flush()) return solveEpoch(*epoch);
  return std::nullopt;
}

std::optional<PoseEstimate> MultilaterationEstimator::solveEpoch(
    const std::vector<AcceptedRange>& epoch) {
  const auto planar = toPlanar(epoch, params_.front.sigma);
  uwb::Fix fix;
  switch (solver_) {
    case MultilaterationSolver::kLinearLS:
      fix = uwb::solveLinearLS(planar);
      break;
    case MultilaterationSolver::kGaussNewton:
      fix = uwb::solveGaussNewton(planar);
      break;
    case MultilaterationSolver::kChan:
      fix = uwb::solveChan(planar);
      break;
  }
  if (!fix.ok()) {
    countRejection(std::string("epoch_") + uwb::toString(fix.status));
    return std::nullopt;
  }
  const double t = epochTime(epoch);
  if (last_tag_ && t > last_t_) heading_.update((fix.position - *last_tag_) / (t - last_t_));
  last_tag_ = fix.position;
  last_t_ = t;

  return kalman::tagTrackPose(t, fix.position, fix.covariance,
                              epoch.front().measurement.tag_on_robot, heading_.heading());
}

}  // namespace uwbloc::loc
