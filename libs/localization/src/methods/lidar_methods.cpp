// Registration of the LiDAR-based methods.
#include <map>

#include "uwbloc/localization/methods/lidar_icp.hpp"
#include "uwbloc/localization/methods/particle_localizer.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::loc {

namespace {

// A particle-filter method: the parts its parameters name (see PfMethodParams), and only the
// defaults in which this variant differs from the parts' own (applied unless the user sets them,
// and shown by `uwbloc methods`).
template <class... Parts>
MethodInfo pfMethod(const std::string& name, const std::string& description,
                    std::vector<std::string> needs, std::map<std::string, std::string> differs) {
  using Params = PfMethodParams<Parts...>;
  auto info = makeMethod<ParticleLocalizer, Params>(
      name, description, std::move(needs),
      [](const Params& p, const EstimatorContext& ctx) { return makeParticleLocalizer(p, ctx); });
  auto make = info.make;
  info.make = [make, differs](ParamSet& set, const EstimatorContext& ctx) {
    for (const auto& [key, value] : differs)
      if (!set.has(key)) set.set(key, value);
    return make(set, ctx);
  };
  for (auto& d : info.defaults)
    if (auto it = differs.find(d.key); it != differs.end()) d.value = it->second;
  return info;
}

using Lidar = LidarPartParams;
using Uwb = UwbPartParams;
using Swarm = SwarmPartParams;

}  // namespace

void addLidarMethods(Registry& r) {
  r.add(makeMethod<LidarIcp, LidarIcpParams>(
      "lidar-icp", "LiDAR odometry: scan-to-scan ICP seeded by odometry, from the start pose",
      {"scans"}));
  const std::vector<std::string> fused{"scans", "odometry", "map", "ranges"};
  r.add(pfMethod<Lidar>("lidar-mcl",
                        "LiDAR only: Monte-Carlo localisation on the map's likelihood field",
                        {"scans", "odometry", "map"}, {{"landmarks", "1"}}));
  // The textbook baseline: no NLOS test and the fixed range model it starts with.
  r.add(pfMethod<Lidar, Uwb>("fused-naive",
                             "LiDAR + UWB particle filter, likelihoods multiplied, no NLOS "
                             "rejection, no learnt range model",
                             fused, {{"nlos", "none"}, {"calib", "0"}}));
  r.add(pfMethod<Lidar, Uwb>("fused-pf",
                             "LiDAR + UWB particle filter with NLOS rejection from the LiDAR pose",
                             fused, {}));
  r.add(pfMethod<Lidar, Uwb>("pf-sir",
                             "PF-IBAS's baseline: fused-pf with n=200 and standard resampling",
                             fused, {{"n", "200"}}));
  r.add(pfMethod<Lidar, Uwb, Swarm>(
      "pf-ibas",
      "The core method: LiDAR + UWB, NLOS rejection, particles moved by the improved beetle "
      "swarm instead of resampled (n=40, up to 400 by KLD-sampling when the posterior spreads)",
      fused, {{"n", "40"}, {"n_max", "400"}}));
  r.add(pfMethod<Lidar, Uwb, Swarm>(
      "pf-ibas-stratified",
      "pf-ibas whose degeneracy step resamples by stratified instead of systematic resampling",
      fused, {{"n", "40"}, {"n_max", "400"}, {"resampler", "stratified"}}));
  r.add(pfMethod<Uwb>("uwb-pf",
                      "UWB + odometry particle filter (the UWB single-sensor particle baseline), "
                      "NLOS test against the odometry-predicted pose",
                      {"odometry", "ranges"}, {{"a_scale", "auto"}}));
}

}  // namespace uwbloc::loc
