// Scores UWB NLOS detectors against ground truth: a range is "bad" when it differs from the
// distance predicted from the ground-truth pose by more than `bad_threshold`.
#pragma once

#include <vector>

#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/localization/estimator.hpp"

namespace uwbloc::eval {

struct DetectorScore {
  long bad = 0, good = 0;  ///< ranges in each class that were judged
  long bad_flagged = 0, good_flagged = 0;
  double recall() const { return bad ? static_cast<double>(bad_flagged) / bad : NAN; }
  double false_alarm() const { return good ? static_cast<double>(good_flagged) / good : NAN; }
};

struct NlosScores {
  DetectorScore pose;     ///< the pose-based test
  DetectorScore raycast;  ///< the map ray-cast
  DetectorScore state;    ///< the links' tracked NLOS state, P(NLOS) > 0.5 (where it is tracked)
};

/// Scores the recorded decisions. `anchor` restricts the bad class to one anchor (the recall of
/// the acceptance test counts beacon 1's bad ranges); -1 counts every anchor. Good ranges of
/// every anchor count for the false-alarm rate.
NlosScores scoreNlos(const data::Dataset& dataset, const std::vector<loc::RangeDecision>& decisions,
                     double bad_threshold = 0.5, int anchor = -1);

}  // namespace uwbloc::eval
