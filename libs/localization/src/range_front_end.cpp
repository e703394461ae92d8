#include "uwbloc/localization/range_front_end.hpp"

#include <algorithm>
#include <cmath>

#include "uwbloc/localization/motion_models.hpp"
#include "uwbloc/localization/params.hpp"
#include "uwbloc/nlos/model.hpp"
#include "uwbloc/uwb/range_model.hpp"

namespace uwbloc::loc {

std::shared_ptr<const nlos::Model> resolveNlosModel(const RangeFrontEndParams& params,
                                                    const EstimatorContext& context) {
  if (params.nlos_model.empty()) return nullptr;
  std::string name = params.nlos_model;
  if (name.rfind("model:", 0) == 0) name = name.substr(6);
  if (!context.nlos_models)
    throw ParamError("nlos_model: " + name +
                     ": this caller gives the methods no model loader (EstimatorContext::"
                     "nlos_models)");
  std::shared_ptr<const nlos::Model> model;
  try {
    model = context.nlos_models(name);
  } catch (const nlos::DataError& e) {
    throw ParamError(std::string("nlos_model: ") + e.what());
  }
  if (!model) throw ParamError("nlos_model: " + name + ": no such model");
  if (model->set == nlos::FeatureSet::kCir || model->set == nlos::FeatureSet::kCirRaw)
    throw ParamError("nlos_model: " + name + " uses the '" + nlos::toString(model->set) +
                     "' features (CIR diagnostics), which a range does not carry: train it with "
                     "--features power or sagehusa");
  return model;
}

int primaryTag(const EstimatorContext& context) {
  return context.robot_tags.empty()
             ? 0
             : *std::min_element(context.robot_tags.begin(), context.robot_tags.end());
}

TagUse tagUse(RobotTags tags, const EstimatorContext& context) {
  return tags == RobotTags::kAuto && context.robot_tags.size() >= 2 ? TagUse::kAll
                                                                    : TagUse::kPrimary;
}

RangeFrontEnd::RangeFrontEnd(const RangeFrontEndParams& params, std::vector<uwb::Anchor> anchors,
                             std::shared_ptr<const nlos::Model> nlos, TagUse tags, int primary_tag)
    : params_(params),
      nlos_(std::move(nlos)),
      anchors_(std::move(anchors)),
      increments_(uwb::IncrementQueueParams{params.iq_length, params.iq_zeta, params.iq_max_speed,
                                            params.iq_floor, 10}),
      tags_(tags),
      primary_tag_(primary_tag),
      mobile_(params.mobile_window, params.mobile_var.value, params.sigmaValue()) {
  if (nlos_ && nlos_->centred) centre_.emplace(nlos_->set);
}

void MobileAnchors::add(const uwb::Range& range, const std::vector<uwb::Anchor>& fixed) {
  const uwb::Anchor* a = uwb::findAnchor(fixed, range.anchor_id);
  if (!a || !std::isfinite(range.range) || range.range <= 0.0) return;
  Node& node = nodes_[range.tag_id];
  const bool repeated = std::find(node.epoch_anchors.begin(), node.epoch_anchors.end(),
                                  range.anchor_id) != node.epoch_anchors.end();
  if (!node.epoch.empty() && (repeated || range.t - node.epoch_t > 0.5)) solve(node);
  if (node.epoch.empty()) node.epoch_t = range.t;
  node.height = range.tag_on_robot.z();
  const auto planar = uwb::projectToPlane(range.range, a->position.z() - node.height);
  if (!planar) return;
  node.epoch.push_back({a->position.head<2>(), *planar, sigma_});
  node.epoch_anchors.push_back(range.anchor_id);
}

void MobileAnchors::solve(Node& node) {
  const uwb::Fix fix = uwb::solveGaussNewton(node.epoch);
  const double t = node.epoch_t;
  node.epoch.clear();
  node.epoch_anchors.clear();
  if (!fix.ok() || !fix.position.allFinite()) return;
  const auto w = static_cast<size_t>(window_);
  if (node.fixes.size() < w) {
    node.fixes.push_back(fix.position);
    node.fix_var.push_back(fix.covariance.diagonal());
  } else {
    node.fixes[node.count % w] = fix.position;
    node.fix_var[node.count % w] = fix.covariance.diagonal();
  }
  ++node.count;
  node.last_fix_t = t;
  node.still = false;
  if (node.fixes.size() < w) return;
  // Per axis, the median and the spread 1.4826 MAD (squared): robust to the odd fix that three
  // anchors flip to the mirror side.
  Eigen::Vector2d mean, var, predicted = Eigen::Vector2d::Zero();
  for (const auto& v : node.fix_var) predicted += v;
  predicted /= static_cast<double>(w);
  std::vector<double>& v = scratch_;  // reuses its storage
  for (int axis = 0; axis < 2; ++axis) {
    v.clear();
    for (const auto& f : node.fixes) v.push_back(f(axis));
    std::nth_element(v.begin(), v.begin() + static_cast<long>(w / 2), v.end());
    const double median = v[w / 2];
    for (auto& x : v) x = std::abs(x - median);
    std::nth_element(v.begin(), v.begin() + static_cast<long>(w / 2), v.end());
    mean(axis) = median;
    var(axis) = std::pow(1.4826 * v[w / 2], 2);
  }
  const Eigen::Vector2d limit =
      variance_ ? Eigen::Vector2d::Constant(*variance_) : Eigen::Vector2d(4.0 * predicted);
  node.still = var.x() < limit.x() && var.y() < limit.y();
  node.mean = mean;
  node.mean_var = 0.5 * var.sum();
}

double MobileAnchors::positionVariance(int id) const {
  const auto it = nodes_.find(id - uwb::kMobileAnchorBase);
  return it == nodes_.end() ? 0.0 : it->second.mean_var;
}

std::optional<uwb::Anchor> MobileAnchors::anchor(int id, double t) const {
  const auto it = nodes_.find(id - uwb::kMobileAnchorBase);
  if (it == nodes_.end() || !it->second.still || t - it->second.last_fix_t > 2.0)
    return std::nullopt;
  return uwb::Anchor{id,
                     Eigen::Vector3d(it->second.mean.x(), it->second.mean.y(), it->second.height)};
}

bool RangeFrontEnd::judge(AcceptedRange& r) {
  auto& m = r.measurement;
  if (!m.rx_power_dbm || !m.fp_power_dbm) {
    r.nlos_decision = "nlos_no_powers";
    return true;
  }
  nlos::Sample sample = nlos::sampleOf(m);
  if (centre_) {
    // A centred model judges a range by where it stands among this place's ranges: until
    // there are enough of them to say, the range passes as measured.
    centre_->add(nlos::features(nlos_->set, sample));
    sample.centre = centre_->centre();
    if (!sample.centre) {
      r.nlos_decision = "nlos_warming_up";
      return true;
    }
  }
  const nlos::Judgement j = nlos_->judge(sample);
  m.nlos_probability = j.p_nlos;
  const double sigma = params_.sigmaValue();
  switch (params_.nlos_use) {
    case NlosUse::kWeight:
      r.variance_scale = 1.0 / (1.0 - std::min(j.p_nlos, 0.99));
      r.nlos_decision = "nlos_weighted";
      break;
    case NlosUse::kCorrect: {
      m.range -= j.error;
      const double dz = r.anchor.z() - m.tag_on_robot.z();
      const auto planar = uwb::projectToPlane(m.range, dz);
      if (!planar) return false;
      r.planar = *planar;
      r.variance_scale = 1.0 + (j.error_sigma * j.error_sigma) / (sigma * sigma);
      r.nlos_decision = "nlos_corrected";
      break;
    }
    case NlosUse::kReject:
      if (j.p_nlos >= params_.nlos_reject) return false;
      r.nlos_decision = "nlos_kept";
      break;
  }
  return true;
}

std::optional<AcceptedRange> RangeFrontEnd::accept(const uwb::Range& range,
                                                   uwb::RejectReason* reason) {
  auto fail = [&](uwb::RejectReason r) {
    if (reason) *reason = r;
    return std::nullopt;
  };
  if (!range.on_robot) {
    if (params_.mobile_anchors) mobile_.add(range, anchors_);
    return fail(uwb::RejectReason::kOtherTag);
  }
  if (tags_ == TagUse::kPrimary && range.tag_id != primary_tag_)
    return fail(uwb::RejectReason::kSecondaryTag);
  if (auto bad = uwb::checkValidity(range.range, {1e-3, params_.max_range})) return fail(*bad);
  const uwb::Anchor* anchor = uwb::findAnchor(anchors_, range.anchor_id);
  std::optional<uwb::Anchor> mobile;
  if (!anchor && range.anchor_id >= uwb::kMobileAnchorBase && params_.mobile_anchors) {
    mobile = mobile_.anchor(range.anchor_id, range.t);
    if (!mobile) return fail(uwb::RejectReason::kMobileMoving);
    anchor = &*mobile;
  }
  if (!anchor) return fail(uwb::RejectReason::kUnknownAnchor);
  if (range.t < last_t_ - 1e-9) return fail(uwb::RejectReason::kTimeBackwards);
  last_t_ = std::max(last_t_, range.t);
  const double dz = anchor->position.z() - range.tag_on_robot.z();
  const auto planar = uwb::projectToPlane(range.range, dz);
  if (!planar) return fail(uwb::RejectReason::kBelowHeight);
  if (params_.increment_gate &&
      !increments_.accept(range.anchor_id, range.t, range.range, range.tag_id))
    return fail(uwb::RejectReason::kIncrement);
  AcceptedRange accepted{range, anchor->position, *planar};
  // A mobile node's position is known to its fixes' scatter only: the range carries it too.
  if (mobile) {
    const double sigma = params_.sigmaValue();
    accepted.variance_scale = 1.0 + mobile_.positionVariance(range.anchor_id) / (sigma * sigma);
  }
  if (nlos_ && !judge(accepted)) return fail(uwb::RejectReason::kNlosModel);
  return accepted;
}

std::optional<AcceptedRange> UwbEstimator::acceptRange(const Event& event) {
  const auto* range = std::get_if<uwb::Range>(&event);
  if (!range) return std::nullopt;
  uwb::RejectReason reason{};
  auto accepted = front_.accept(*range, &reason);
  if (!accepted) {
    rejectRange(stats_, *range, uwb::toString(reason));
    return std::nullopt;
  }
  ++stats_.accepted_ranges;
  if (accepted->nlos_decision) ++stats_.events[accepted->nlos_decision];
  return accepted;
}

bool UwbEstimator::correctRange(AcceptedRange& r, const RangeNoiseModel& model) {
  const int id = r.measurement.anchor_id;
  if (model.scale() == 0.0 && model.bias(id) == 0.0) return true;
  r.measurement.range = model.correct(id, r.measurement.range);
  const auto planar =
      uwb::projectToPlane(r.measurement.range, r.anchor.z() - r.measurement.tag_on_robot.z());
  if (!planar) {
    countRejection(uwb::RejectReason::kBelowHeight, id);
    return false;
  }
  r.planar = *planar;
  return true;
}

EpochUwbEstimator::EpochUwbEstimator(const RangeFrontEndParams& params,
                                     const EstimatorContext& context, AutoDouble window,
                                     TagUse tags, const RangeLearningParams& learning,
                                     const AutoDouble* q)
    : UwbEstimator(params, context, tags),
      tags_(tags),
      primary_tag_(primaryTag(context)),
      epochs_(window),
      primary_track_{FixContinuity(FixContinuityParams{params.iq_max_speed, params.iq_floor})},
      initial_pose_(context.initial_pose),
      initial_time_(context.initial_time),
      sigma_auto_(params.sigma.isAuto()),
      calib_bias_(learning.calib_bias),
      sigma_(params.sigmaValue()),
      noise_(params.sigmaValue()) {
  start_ = makeLearningStart(params.sigma, q, learning, context);
}

void EpochUwbEstimator::learn(const EstimatorStatistics& learnt) {
  noise_.learnFrom(learnt, calib_bias_, sigma_auto_);
  noise_.report(stats_);
  if (sigma_auto_ && !estimatesOwnNoise() && learnt.estimated_range_sigma)
    sigma_ = noise_.widened(sigma_, stats_);
  countLearnt(learnt, stats_);
  // The learnt path's speed, three times its RMS, where it exceeds the plausible one.
  // The continuity track's acceleration: twice the density the learnt path showed, so that its
  // gate admits motion livelier than the first minute's. Every tag's track.
  auto adjust = [&learnt](FixContinuity& c) {
    if (learnt.mean_square_speed) c.raiseMaxSpeed(3.0 * std::sqrt(*learnt.mean_square_speed));
    if (learnt.estimated_accel_psd) c.setAccelPsd(2.0 * *learnt.estimated_accel_psd);
  };
  adjust(primary_track_.continuity);
  for (auto& [tag, t] : other_tracks_) adjust(t.continuity);
}

std::optional<PoseEstimate> EpochUwbEstimator::step(const Event& event) {
  auto accepted = acceptRange(event);
  if (!accepted || !correctRange(*accepted, noise_)) return std::nullopt;
  if (auto epoch = epochs_.add(*accepted)) return onEpoch(*epoch);
  return std::nullopt;
}

std::optional<PoseEstimate> EpochUwbEstimator::doProcess(const Event& event) {
  return start_.process(event, learnt_, step_);
}

std::vector<PoseEstimate> EpochUwbEstimator::doFinishAll() {
  auto out = start_.finish(learnt_, step_);
  if (auto epoch = epochs_.flush())
    if (auto last = onEpoch(*epoch)) out.push_back(*last);
  return out;
}

EpochUwbEstimator::TagTrack& EpochUwbEstimator::track(int tag) {
  if (tag == primary_tag_) return primary_track_;
  auto it = other_tracks_.find(tag);
  if (it == other_tracks_.end())
    it = other_tracks_.emplace(tag, TagTrack{primary_track_.continuity.fresh()}).first;
  return it->second;
}

std::optional<uwb::Fix> EpochUwbEstimator::epochFixOn(TagTrack& track, MultilaterationSolver solver,
                                                      double t,
                                                      const std::vector<AcceptedRange>& epoch,
                                                      std::vector<uwb::PlanarRange> planar,
                                                      bool continuity, bool deskew) {
  if (continuity && deskew) {
    if (auto motion = track.continuity.motion(t))
      planar = deskewRanges(epoch, std::move(planar), t, *motion);
  }
  const uwb::Fix fix = multilaterate(solver, planar);
  if (!fix.ok()) {
    // Two ranges give no fix, but the continuity track follows the intersection it predicts, so
    // that the next fix is judged from a recent position (emitting it as a fix measured worse:
    // Hanyang NLOS A1, uwb-kf 0.837 -> 0.900 m).
    if (continuity && track.seeded && planar.size() == 2 &&
        track.continuity.checkTwo(t, planar).fix)
      ++stats_.events[toString(Continuity::kTwoRanges)];
    countRejection(std::string("epoch_") + uwb::toString(fix.status));
    return std::nullopt;
  }
  if (!continuity) return fix;
  std::optional<Eigen::Vector2d> seed;
  if (initial_pose_) seed = tagFromRobot(*initial_pose_, epoch.front().measurement.tag_on_robot);
  return checkedOn(
             track, t, epoch, fix, planar,
             [&](const auto& subset) { return multilaterate(solver, subset); },
             Eigen::Vector2d::Zero(), seed)
      .fix;
}

namespace {
// The 99.9 % point of the chi-square distribution with k degrees of freedom (Wilson-Hilferty:
// within 3 % of the exact value from k = 1: 11.2 against 10.83).
double chiSquare999(int k) {
  const double a = 2.0 / (9.0 * k);
  return k * std::pow(1.0 - a + 3.0902 * std::sqrt(a), 3);
}
}  // namespace

TagsEpoch EpochUwbEstimator::tagsEpoch(MultilaterationSolver solver,
                                       const std::vector<AcceptedRange>& epoch, bool continuity,
                                       bool deskew) {
  TagsEpoch out;
  if (!readsEveryTag()) {
    out.primary = epochFixOn(primary_track_, solver, epochTime(epoch), epoch,
                             toPlanar(epoch, sigma_), continuity, deskew);
    out.primary_lever = epoch.front().measurement.tag_on_robot;
    return out;
  }
  std::map<int, std::vector<AcceptedRange>> by_tag;
  for (const auto& r : epoch) by_tag[r.measurement.tag_id].push_back(r);
  const double t = epochTime(epoch);
  struct Tag {
    int id;
    const std::vector<AcceptedRange>* ranges;
    double residual_norm;
  };
  std::vector<std::pair<Tag, uwb::Fix>> fixed;
  for (const auto& [id, ranges] : by_tag) {
    // Every tag's point at the epoch's time, so that the lever arms fit points of one instant
    // (tags that range in turn take their ranges at different times).
    auto fix =
        epochFixOn(track(id), solver, t, ranges, toPlanar(ranges, sigma_), continuity, deskew);
    if (id == primary_tag_) {
      out.primary = fix;
      primary_lever_ = ranges.front().measurement.tag_on_robot;
    }
    if (!fix) continue;
    // The fix's residual variance per degree of freedom k = n - 2, over the median of
    // chi-square_k / k (Wilson-Hilferty), so that the window's median is the range variance.
    if (ranges.size() > 2) {
      const double k = static_cast<double>(ranges.size() - 2);
      fix_variances_.add(fix->residual_norm * fix->residual_norm /
                         (k * std::pow(1.0 - 2.0 / (9.0 * k), 3)));
    }
    fixed.push_back({{id, &ranges, fix->residual_norm}, *fix});
  }
  // The fixes' covariances come from the std in force; the fit and its tests take them at the
  // range variance the tags' fixes show (as uwb-multitag does), once five fixes tell it. A tag
  // whose own ranges disagree (four or more: chi-square of n - 2 degrees of freedom beyond its
  // 99.9 % point) is left out before the fit: the others place the robot without it.
  std::optional<double> variance;
  if (fix_variances_.size() >= 5) variance = std::max(fix_variances_.median(), 1e-6);
  std::vector<Tag> tags;
  std::vector<uwb::BodyPoint> points;
  for (auto& [tag, fix] : fixed) {
    const int n = static_cast<int>(tag.ranges->size());
    if (variance && n >= 4 &&
        fix.residual_norm * fix.residual_norm > *variance * chiSquare999(n - 2)) {
      for (const auto& r : *tag.ranges) countRejection("tag_fix_left_out", r.measurement.anchor_id);
      if (tag.id == primary_tag_) out.primary.reset();  // nor is it the fallback
      continue;
    }
    if (variance) fix.covariance *= *variance / (sigma_ * sigma_);
    tags.push_back(tag);
    points.push_back(
        {tag.ranges->front().measurement.tag_on_robot.head<2>(), fix.position, fix.covariance});
  }
  auto fit = uwb::fitRigidBody(points);
  while (fit && fit->chi2 > chiSquare999(2 * static_cast<int>(points.size()) - 3)) {
    if (points.size() == 2) {
      ++stats_.events["tags_fix_inconsistent"];
      fit.reset();
      break;
    }
    // The tag whose leaving out fits the others best (a wrong point pulls the fit, and its
    // residual may show on another point).
    std::optional<uwb::RigidFit> best;
    size_t worst = 0;
    for (size_t k = 0; k < points.size(); ++k) {
      std::vector<uwb::BodyPoint> others = points;
      others.erase(others.begin() + static_cast<long>(k));
      auto f = uwb::fitRigidBody(others);
      if (f && (!best || f->chi2 < best->chi2)) {
        best = std::move(f);
        worst = k;
      }
    }
    for (const auto& r : *tags[worst].ranges)
      countRejection("tag_fix_left_out", r.measurement.anchor_id);
    if (tags[worst].id == primary_tag_) out.primary.reset();
    tags.erase(tags.begin() + static_cast<long>(worst));
    points.erase(points.begin() + static_cast<long>(worst));
    fit = std::move(best);
  }
  if (primary_lever_) out.primary_lever = *primary_lever_;
  if (!fit || !primary_lever_) {
    // The primary tag's own fix stands, unless it was left out (then nothing does): the others'
    // ranges go unused.
    for (const auto& [id, ranges] : by_tag)
      if (id != primary_tag_)
        for (const auto& r : ranges) countRejection("secondary_tag", r.measurement.anchor_id);
    return out;
  }
  out.fit = fit;
  // The primary tag's point, J Sigma J^T with J = d(t + R(theta) l)/d(t, theta) = [I, R' l].
  const Eigen::Vector2d lever = out.primary_lever.head<2>();
  Eigen::Matrix<double, 2, 3> j;
  j << Eigen::Matrix2d::Identity(), rotationDerivative(fit->pose.z()) * lever;
  uwb::Fix p;
  p.status = uwb::FixStatus::kOk;
  p.position = transformPoint(fit->pose, lever);
  p.covariance = j * fit->covariance * j.transpose();
  double sum = 0.0;
  for (const auto& tag : tags) sum += tag.residual_norm * tag.residual_norm;
  p.residual_norm = std::sqrt(sum);
  out.primary = p;
  return out;
}

FixContinuity::Checked EpochUwbEstimator::continuityChecked(
    const std::vector<AcceptedRange>& epoch, const uwb::Fix& fix,
    const std::vector<uwb::PlanarRange>& planar, const FixContinuity::Solver& solve,
    const Eigen::Vector2d& offset, const std::optional<Eigen::Vector2d>& seed) {
  return checkedOn(primary_track_, epochTime(epoch), epoch, fix, planar, solve, offset, seed);
}

FixContinuity::Checked EpochUwbEstimator::checkedOn(
    TagTrack& track, double t, const std::vector<AcceptedRange>& epoch, const uwb::Fix& fix,
    const std::vector<uwb::PlanarRange>& planar, const FixContinuity::Solver& solve,
    const Eigen::Vector2d& offset, const std::optional<Eigen::Vector2d>& seed) {
  if (!track.seeded && seed) track.continuity.seed(initial_time_, *seed);
  track.seeded = true;
  auto checked = track.continuity.check(t, fix, planar, solve, offset);
  if (checked.outcome == Continuity::kUnreachable) {
    countRejection(toString(checked.outcome));
  } else if (checked.outcome != Continuity::kAsIs) {
    ++stats_.events[toString(checked.outcome)];
    for (int i : checked.left_out)
      countRejection("fix_continuity_left_out",
                     epoch[static_cast<size_t>(i)].measurement.anchor_id);
  }
  return checked;
}

uwb::Fix multilaterate(MultilaterationSolver solver, const std::vector<uwb::PlanarRange>& ranges) {
  switch (solver) {
    case MultilaterationSolver::kGaussNewton:
      return uwb::solveGaussNewton(ranges);
    case MultilaterationSolver::kChan:
      return uwb::solveChan(ranges);
    case MultilaterationSolver::kLinearLS:
      break;
  }
  return uwb::solveLinearLS(ranges);
}

double EpochBuffer::window() const {
  if (window_.value) return *window_.value;
  if (tags_seen_.size() >= 2) {
    if (round_spans_.size() == 0) return kMinEpochWindow;
    return std::max(kMinEpochWindow, 1.2 * round_spans_.median());
  }
  if (gaps_.size() == 0 || anchors_seen_.size() < 2) return kMinEpochWindow;
  const double round = 1.2 * static_cast<double>(anchors_seen_.size() - 1) * gaps_.median();
  return std::max(kMinEpochWindow, round);
}

std::optional<std::vector<AcceptedRange>> EpochBuffer::add(const AcceptedRange& r) {
  const double t = r.measurement.t;
  if (!anchors_seen_.empty()) gaps_.add(std::max(0.0, t - last_t_));  // not the first range
  const std::pair<int, int> link{r.measurement.anchor_id, r.measurement.tag_id};
  if (std::find(round_links_.begin(), round_links_.end(), link) != round_links_.end()) {
    round_spans_.add(std::max(0.0, last_t_ - round_start_));
    round_links_.clear();
  }
  if (round_links_.empty()) round_start_ = t;
  round_links_.push_back(link);
  last_t_ = t;
  if (std::find(anchors_seen_.begin(), anchors_seen_.end(), r.measurement.anchor_id) ==
      anchors_seen_.end())
    anchors_seen_.push_back(r.measurement.anchor_id);
  if (std::find(tags_seen_.begin(), tags_seen_.end(), r.measurement.tag_id) == tags_seen_.end())
    tags_seen_.push_back(r.measurement.tag_id);
  std::optional<std::vector<AcceptedRange>> closed;
  if (!open_.empty()) {
    const bool too_late = r.measurement.t - open_.front().measurement.t > window();
    const bool repeated = std::any_of(open_.begin(), open_.end(), [&](const AcceptedRange& o) {
      return o.measurement.anchor_id == r.measurement.anchor_id &&
             o.measurement.tag_id == r.measurement.tag_id;
    });
    if (too_late || repeated) {
      closed = std::move(open_);
      open_.clear();
    }
  }
  open_.push_back(r);
  return closed;
}

std::optional<std::vector<AcceptedRange>> EpochBuffer::flush() {
  if (open_.empty()) return std::nullopt;
  std::vector<AcceptedRange> out = std::move(open_);
  open_.clear();
  return out;
}

std::vector<uwb::PlanarRange> toPlanar(const std::vector<AcceptedRange>& epoch, double sigma) {
  std::vector<uwb::PlanarRange> out;
  out.reserve(epoch.size());
  for (const auto& r : epoch)
    out.push_back({r.anchor.head<2>(), r.planar, sigma * std::sqrt(r.variance_scale)});
  return out;
}

double epochTime(const std::vector<AcceptedRange>& epoch) {
  // Relative to the first stamp, so that the sum of epoch stamps ~1e9 s loses no precision.
  const double t0 = epoch.front().measurement.t;
  double offset = 0.0;
  for (const auto& r : epoch) offset += r.measurement.t - t0;
  return t0 + offset / static_cast<double>(epoch.size());
}

std::vector<uwb::PlanarRange> deskewRanges(const std::vector<AcceptedRange>& epoch,
                                           std::vector<uwb::PlanarRange> planar, double t,
                                           const FixContinuity::Motion& motion) {
  // The velocity shrunk by the share its uncertainty takes of it: moving a range by u.v dt trades
  // the skew's error for the velocity's (dt (u^T C_v u)^0.5); a velocity no surer than its own
  // size moves nothing (Hanyang LOS A1's fixes 37-47 m from clustered anchors swing the track's
  // to 3 +- 3.6 m/s).
  const double v2 = motion.velocity.squaredNorm();
  const double trace = motion.velocity_cov.trace();
  if (!(v2 > trace)) return planar;
  const Eigen::Vector2d v = (1.0 - trace / v2) * motion.velocity;
  for (size_t i = 0; i < planar.size() && i < epoch.size(); ++i) {
    const double dt = t - epoch[i].measurement.t;
    const Eigen::Vector2d d = motion.position - planar[i].anchor;
    if (dt == 0.0 || !(d.norm() > 1e-9)) continue;
    const Eigen::Vector2d u = d.normalized();
    auto& r = planar[i];
    r.range = std::max(0.0, r.range + u.dot(v) * dt);
    r.sigma = std::sqrt(r.sigma * r.sigma + u.dot(motion.velocity_cov * u) * dt * dt);
  }
  return planar;
}

std::optional<uwb::Fix> consistentFix(const std::vector<AcceptedRange>& epoch, double sigma,
                                      double max_residual, EstimatorStatistics& stats,
                                      const std::string& prefix) {
  const uwb::Fix fix = uwb::solveGaussNewton(toPlanar(epoch, sigma));
  if (!fix.ok()) {
    countRejection(stats, prefix + uwb::toString(fix.status));
    return std::nullopt;
  }
  if (fix.residual_norm > max_residual) {
    countRejection(stats, "init_inconsistent_fix");
    return std::nullopt;
  }
  return fix;
}

}  // namespace uwbloc::loc
