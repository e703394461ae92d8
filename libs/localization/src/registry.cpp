#include "uwbloc/localization/registry.hpp"

#include "uwbloc/localization/methods/federated_ekf.hpp"
#include "uwbloc/localization/methods/graph_smoother.hpp"
#include "uwbloc/localization/methods/multilateration_estimator.hpp"
#include "uwbloc/localization/methods/odometry_estimator.hpp"
#include "uwbloc/localization/methods/point_filters.hpp"
#include "uwbloc/localization/methods/uwb_akf.hpp"
#include "uwbloc/localization/methods/uwb_ctrv_ekf.hpp"
#include "uwbloc/localization/methods/uwb_ekf.hpp"
#include "uwbloc/localization/methods/uwb_ins.hpp"
#include "uwbloc/localization/methods/uwb_kf.hpp"
#include "uwbloc/localization/methods/uwb_multitag.hpp"
#include "uwbloc/localization/methods/uwb_shkf.hpp"

namespace uwbloc::loc {

void addLidarMethods(Registry& r);  // lidar_methods.cpp

namespace {

MethodInfo multilaterationMethod(const std::string& name, const std::string& description,
                                 MultilaterationSolver solver) {
  return makeMethod<MultilaterationEstimator, MultilaterationParams>(
      name, description, {"ranges"},
      [solver](const MultilaterationParams& p, const EstimatorContext& ctx) {
        return std::make_unique<MultilaterationEstimator>(solver, p, ctx);
      });
}

// A range filter (uwb_ekf.hpp): Filter<6> on every tag when the robot carries two or more and the
// key tags is auto, else Filter<4> on the primary tag.
RobotTags tagsOf(const UwbEkfParams& p) { return p.tags; }
RobotTags tagsOf(const UwbCkfParams& p) { return p.ekf.tags; }
RobotTags tagsOf(const UwbIahCkfParams& p) { return p.ckf.ekf.tags; }
RobotTags tagsOf(const UwbSrukfParams& p) { return p.ekf.tags; }
RobotTags tagsOf(const UwbShkfParams& p) { return p.ekf.tags; }
RobotTags tagsOf(const FederatedEkfParams& p) { return p.ekf.tags; }

template <template <int> class Filter, class Params>
MethodInfo rangeFilterMethod(const std::string& name, const std::string& description) {
  return makeMethod<Filter<4>, Params>(name, description, {"ranges"},
                                       [](const Params& p, const EstimatorContext& ctx) {
                                         return makeRangeFilter<Filter>(p, tagsOf(p), ctx);
                                       });
}

// A registered method whose parameter `key` defaults to `value` (another method's estimator with
// one default changed): applied unless the spec, --set or --config gives the key.
MethodInfo withDefault(MethodInfo info, const std::string& key, const std::string& value) {
  auto make = info.make;
  info.make = [make, key, value](ParamSet& set, const EstimatorContext& ctx) {
    if (!set.has(key)) set.set(key, value);
    return make(set, ctx);
  };
  for (auto& d : info.defaults)
    if (d.key == key) d.value = value;
  return info;
}

Registry makeBuiltin() {
  Registry r;
  r.add(multilaterationMethod("uwb-ls", "UWB only: linearised least squares per epoch",
                              MultilaterationSolver::kLinearLS));
  r.add(multilaterationMethod("uwb-gn", "UWB only: weighted Gauss-Newton per epoch",
                              MultilaterationSolver::kGaussNewton));
  r.add(multilaterationMethod("uwb-chan", "UWB only: Chan's two-step WLS per epoch",
                              MultilaterationSolver::kChan));
  r.add(makeMethod<UwbMultitag, UwbMultitagParams>(
      "uwb-multitag",
      "UWB only: pose and heading per epoch from all the robot's tags (Gauss-Newton on x, y, "
      "theta; closed-form start)",
      {"ranges"}));
  r.add(makeMethod<UwbKf, UwbKfParams>(
      "uwb-kf", "UWB only: constant-velocity KF on multilateration fixes (loosely coupled)",
      {"ranges"}));
  r.add(makeMethod<UwbAkf, UwbAkfParams>(
      "uwb-akf",
      "UWB only: Sage-Husa adaptive KF on multilateration fixes (greenhouse paper eq. 15-16; "
      "mode=ranges: on each range)",
      {"ranges"}, makeUwbAkf));
  r.add(withDefault(makeMethod<UwbAkf, UwbAkfParams>(
                        "uwb-iakf",
                        "UWB only: the greenhouse paper's improved adaptive KF: uwb-akf with the "
                        "divergence test and covariance inflation of eq. 17-23",
                        {"ranges"}, makeUwbAkf),
                    "gamma", "1"));
  r.add(makeMethod<UwbCtrvEkf, UwbCtrvEkfParams>(
      "uwb-ctrv-ekf",
      "UWB only: the mobile-node paper's EKF, constant turn rate and velocity, on multilateration "
      "fixes (solver=ls: the paper's least squares) behind the increment-queue gate",
      {"ranges"}));
  r.add(rangeFilterMethod<UwbEkfT, UwbEkfParams>(
      "uwb-ekf",
      "UWB only: constant-velocity EKF on each range, innovation-gated (tight); with two tags or "
      "more on the robot, on the pose and heading through the lever arms"));
  r.add(rangeFilterMethod<UwbShkfT, UwbShkfParams>(
      "uwb-shkf",
      "UWB only: improved Sage-Husa KF on each range: fading factor, variable window, adaptive "
      "factor; takes a per-range NLOS probability"));
  r.add(rangeFilterMethod<UwbCkfT, UwbCkfParams>(
      "uwb-ckf", "UWB only: cubature KF (third-degree spherical-radial rule) on each range"));
  r.add(withDefault(rangeFilterMethod<UwbCkfT, UwbCkfParams>(
                        "uwb-hinf-ckf",
                        "UWB only: H-infinity cubature KF on each range (hinf: the bound over "
                        "the smallest feasible)"),
                    "hinf", "5"));
  r.add(rangeFilterMethod<UwbIahCkfT, UwbIahCkfParams>(
      "uwb-iahckf",
      "UWB only: the H-infinity cubature paper's improved adaptive filter: H-inf CKF, Sage-Husa "
      "noise per anchor, IGG-III robust factor above the 0.24 m NLOS threshold"));
  r.add(rangeFilterMethod<UwbSrukfT, UwbSrukfParams>(
      "uwb-srukf", "UWB only: square-root unscented KF on each range"));
  r.add(rangeFilterMethod<FederatedEkfT, FederatedEkfParams>(
      "federated-ekf",
      "UWB only: federated EKF, local EKFs on anchor groups fused by information (fusion-reset)"));
  r.add(makeMethod<UwbIns, UwbInsParams>(
      "uwb-ins",
      "UWB/INS: EKF over the planar strapdown (position, velocity, heading, biases), updated "
      "by each range (mode=fix: each fix), ZUPT and ZARU",
      {"ranges", "imu"}));
  r.add(withDefault(
      makeMethod<UwbIns, UwbInsParams>(
          "uwb-ins-ckf", "UWB/INS: uwb-ins with the cubature rule (the H-infinity paper's CKF)",
          {"ranges", "imu"}),
      "filter", "ckf"));
  r.add(withDefault(
      withDefault(withDefault(makeMethod<UwbIns, UwbInsParams>(
                                  "uwb-ins-ickf",
                                  "UWB/INS: the H-infinity paper's ICKF: uwb-ins-ckf with the "
                                  "H-infinity update and the IGG-III factor above the 0.24 m "
                                  "NLOS threshold",
                                  {"ranges", "imu"}),
                              "filter", "ckf"),
                  "hinf", "5"),
      "robust", "1"));
  r.add(makeMethod<OdometryEstimator, OdometryParams>(
      "odom", "Odometry only: dead reckoning from the first ground-truth pose", {"odometry"}));
  addLidarMethods(r);
  r.add(makeMethod<GraphSmoother, GraphSmootherParams>(
      "graph-uwb-odom",
      "Batch smoothing of range + odometry over a Ceres graph (robust loss, optional bias and "
      "anchor self-calibration)",
      {"odometry", "ranges"}));
  r.add(withDefault(makeMethod<GraphSmoother, GraphSmootherParams>(
                        "graph-uwb",
                        "UWB only: batch smoothing of the ranges over a Ceres graph with a "
                        "constant-velocity prior (range std, q, scale and biases learnt)",
                        {"ranges"}),
                    "motion", "cv"));
  r.add(withDefault(makeMethod<GraphSmoother, GraphSmootherParams>(
                        "pf-ibas+graph",
                        "The PF-IBAS paper's full method: PF-IBAS online, then its estimates "
                        "smoothed over a Ceres graph with the ranges and the odometry (front-end "
                        "parameters: front=pf-ibas:k=v;k=v)",
                        {"scans", "odometry", "map", "ranges"}),
                    "front", "pf-ibas"));
  return r;
}

}  // namespace

MethodSpec MethodSpec::parse(const std::string& spec) {
  MethodSpec out;
  out.text = spec;
  const auto colon = spec.find(':');
  out.name = spec.substr(0, colon);
  if (out.name.empty()) throw ParamError("empty method name in '" + spec + "'");
  if (colon != std::string::npos)
    out.params = ParamSet::parse(spec.substr(colon + 1), "method '" + out.name + "'");
  return out;
}

const Registry& Registry::builtin() {
  static const Registry registry = makeBuiltin();
  return registry;
}

void Registry::add(MethodInfo info) { methods_.push_back(std::move(info)); }

const MethodInfo* Registry::find(const std::string& name) const {
  for (const auto& m : methods_)
    if (m.name == name) return &m;
  return nullptr;
}

std::vector<std::string> Registry::names() const {
  std::vector<std::string> out;
  for (const auto& m : methods_) out.push_back(m.name);
  return out;
}

std::string Registry::knownNames() const {
  std::string list;
  for (const auto& m : methods_) list += (list.empty() ? "" : ", ") + m.name;
  return list;
}

std::unique_ptr<Estimator> Registry::create(const std::string& spec,
                                            const EstimatorContext& context,
                                            const ParamSet& extra) const {
  MethodSpec parsed = MethodSpec::parse(spec);
  const MethodInfo* info = find(parsed.name);
  if (!info) throw ParamError("unknown method '" + parsed.name + "' (known: " + knownNames() + ")");
  ParamSet merged = extra;
  merged.merge(parsed.params);  // the spec overrides the config file
  return info->make(merged, context);
}

SetOverride SetOverride::parse(const std::string& text, const Registry& registry) {
  const auto eq = text.find('=');
  const auto dot = eq == std::string::npos ? std::string::npos : text.rfind('.', eq);
  if (eq == std::string::npos || dot == std::string::npos || dot == 0 || dot + 1 == eq)
    throw ParamError("--set expects method.key=value, got " + quoteToken(text));
  SetOverride out{text.substr(0, dot), text.substr(dot + 1, eq - dot - 1), text.substr(eq + 1)};
  if (!registry.find(out.method))
    throw ParamError("--set " + quoteToken(text) + ": " + quoteToken(out.method) +
                     " is not a method (known: " + registry.knownNames() + ")");
  return out;
}

}  // namespace uwbloc::loc
