// Range gates: small classes that accept or reject one range, each for one stated reason.
// Rejections are not errors: callers count them per reason (and per anchor) and report them.
#pragma once

#include <array>
#include <cstddef>
#include <map>
#include <optional>
#include <string>

namespace uwbloc::uwb {

enum class RejectReason {
  kNonFinite,      ///< NaN or infinite range
  kZero,           ///< exactly zero (or below min_range): the device reported no measurement
  kNegative,       ///< negative range
  kBeyondMax,      ///< longer than the configured maximum
  kBelowHeight,    ///< shorter than the tag-anchor height difference (eq. 3 impossible)
  kUnknownAnchor,  ///< anchor id not in the anchor set
  kIncrement,      ///< increment-queue gate
  kChiSquare,      ///< chi-square gate on a residual
  kThreeSigma,     ///< 3-sigma gate on a residual
  kInnovation,     ///< filter innovation gate (Mahalanobis)
  kTimeBackwards,  ///< timestamp earlier than the previous one
  kOtherTag,       ///< measured by another tag (a mobile node), not by the robot's own
  kNlosModel,      ///< an NLOS model judged it NLOS (P >= nlos_reject), or its correction failed
  kSecondaryTag,   ///< from another of the robot's tags: the method tracks one tag point
  kMobileMoving,   ///< to a mobile node that is not (or no longer) still enough to be an anchor
};

/// Stable snake_case names used in metrics.json's "rejected" map.
const char* toString(RejectReason r);

struct ValidityParams {
  double min_range = 1e-3;   ///< ranges at or below this are "zero" readings [m]
  double max_range = 100.0;  ///< ranges above this are absurd [m]
};

/// Rejects non-finite, zero, negative and beyond-maximum ranges.
std::optional<RejectReason> checkValidity(double range, const ValidityParams& params = {});

struct IncrementQueueParams {
  int queue_length = 5;              ///< n, the paper's queue length
  double zeta = 3.0;                 ///< ζ, scale on the mean recent increment
  double max_speed = 2.0;            ///< v_max, fastest plausible tag speed [m/s]
  double noise_floor = 0.3;          ///< tolerance for ranging noise [m]
  int max_consecutive_rejects = 10;  ///< after this many, re-seed on the newest range
};

/// Range-increment queue of the mobile-node paper (section 2.1), per anchor (and tag: each
/// anchor-tag link has its own queue).
///
/// For anchor i keep the last accepted range X_i and a ring buffer of its last n accepted
/// increments ΔX_i(t-n+1..t). A new range X_i(t+1) at time t+1 has increment
/// ΔX_i(t+1) = X_i(t+1) - X_i, and is accepted iff the judgement value
///
///   Y_i = ζ · mean_j |ΔX_i(t-j)| + v_max · (t_{t+1} - t_last) + noise_floor - |ΔX_i(t+1)|
///
/// is positive. The paper's Y keeps only the first term (its increments are taken at a fixed
/// 20 Hz with the tag moving); the speed term lets the gate work after gaps and at other rates,
/// and the noise floor keeps a stationary tag (mean increment near 0) from rejecting its own
/// noise. The first range of an anchor is accepted as the reference. After
/// `max_consecutive_rejects` rejections in a row the anchor is re-seeded on the newest range,
/// so that one early outlier cannot lock the anchor out for ever.
class IncrementQueueGate {
 public:
  explicit IncrementQueueGate(IncrementQueueParams params = {}) : params_(params) {}
  /// True when accepted; updates the anchor's queue only then.
  bool accept(int anchor_id, double t, double range, int tag_id = 0);
  int reseeds() const { return reseeds_; }

 private:
  struct AnchorState {
    double last_range = 0.0;
    double last_t = 0.0;
    std::array<double, 32> increments{};
    int count = 0;
    int head = 0;
    int consecutive_rejects = 0;
  };
  IncrementQueueParams params_;
  std::map<std::pair<int, int>, AnchorState> state_;  ///< by (anchor, tag)
  int reseeds_ = 0;
};

/// Chi-square gate on a residual r with variance s: accept iff r^2 / s <= threshold. For a
/// vector innovation y with covariance S, the squared Mahalanobis distance y^T S^-1 y takes the
/// place of r^2 / s (acceptSquared), with the threshold for its degrees of freedom. The one gate
/// of every filter: the Kalman family, the particle filters' NLOS test and landmark association.
/// The default 5.0 is the mobile-node paper's factor for one degree of freedom.
class ChiSquareGate {
 public:
  explicit ChiSquareGate(double threshold = 5.0) : threshold_(threshold) {}
  bool accept(double residual, double variance) const;
  /// Accepts a squared Mahalanobis distance d^2 <= threshold (NaN is rejected).
  bool acceptSquared(double d2) const { return d2 <= threshold_; }
  double threshold() const { return threshold_; }

 private:
  double threshold_;
};

struct ThreeSigmaParams {
  int window = 20;          ///< residuals kept per anchor
  int min_samples = 5;      ///< below this many the gate accepts (still learning)
  double min_sigma = 0.05;  ///< floor on the window's std [m]
  double k = 3.0;           ///< gate width in standard deviations
};

/// 3-sigma gate on residuals per anchor, from a sliding window of that anchor's accepted
/// residuals: reject |r - mean| > k · max(std, min_sigma).
class ThreeSigmaGate {
 public:
  explicit ThreeSigmaGate(ThreeSigmaParams params = {}) : params_(params) {}
  bool accept(int anchor_id, double residual);

 private:
  struct Window {
    std::array<double, 128> values{};
    int count = 0;
    int head = 0;
  };
  ThreeSigmaParams params_;
  std::map<int, Window> windows_;
};

}  // namespace uwbloc::uwb
