// Registration of the LiDAR-based methods.
#include <map>

#include "uwbloc/localization/methods/lidar_icp.hpp"
#include "uwbloc/localization/methods/pf_localizer.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::loc {

namespace {

// A particle-filter method: which sensors it uses and the defaults that differ from
// PfLocalizerParams' (applied unless the user sets them, and shown by `uwbloc methods`).
MethodInfo pfMethod(const std::string& name, const std::string& description,
                    std::vector<std::string> needs, bool lidar, bool uwb,
                    std::map<std::string, std::string> defaults) {
  auto info = makeMethod<PfLocalizer, PfLocalizerParams>(
      name, description, std::move(needs),
      [lidar, uwb](const PfLocalizerParams& p, const EstimatorContext& ctx) {
        return std::make_unique<PfLocalizer>(p, ctx, lidar, uwb);
      });
  auto make = info.make;
  info.make = [make, defaults](ParamSet& set, const EstimatorContext& ctx) {
    for (const auto& [key, value] : defaults)
      if (!set.has(key)) set.set(key, value);
    return make(set, ctx);
  };
  for (auto& d : info.defaults)
    if (auto it = defaults.find(d.key); it != defaults.end()) d.value = it->second;
  return info;
}

}  // namespace

void addLidarMethods(Registry& r) {
  r.add(makeMethod<LidarIcp, LidarIcpParams>(
      "lidar-icp", "LiDAR odometry: scan-to-scan ICP seeded by odometry, from the start pose",
      {"scans"}));
  const std::vector<std::string> fused{"scans", "odometry", "map", "ranges"};
  r.add(pfMethod("lidar-mcl", "LiDAR only: Monte-Carlo localisation on the map's likelihood field",
                 {"scans", "odometry", "map"}, true, false, {{"nlos", "none"}}));
  r.add(pfMethod("fused-naive",
                 "LiDAR + UWB particle filter, likelihoods multiplied, no NLOS rejection", fused,
                 true, true, {{"nlos", "none"}, {"landmarks", "0"}}));
  r.add(pfMethod("fused-pf", "LiDAR + UWB particle filter with NLOS rejection from the LiDAR pose",
                 fused, true, true, {{"nlos", "lidar"}, {"landmarks", "0"}}));
  r.add(pfMethod("pf-sir", "PF-IBAS's baseline: fused-pf with n=200 and standard resampling", fused,
                 true, true, {{"nlos", "lidar"}, {"n", "200"}, {"landmarks", "0"}}));
  r.add(pfMethod("pf-ibas",
                 "The core method: LiDAR + UWB, NLOS rejection, particles moved by the improved "
                 "beetle swarm instead of resampled (n=40)",
                 fused, true, true,
                 {{"nlos", "lidar"},
                  {"n", "40"},
                  {"swarm", "ibas"},
                  {"ibas_iters", "1"},
                  {"ibas_step", "0.1"},
                  {"ibas_theta", "0"},
                  {"ibas_resample", "1"},
                  {"ibas_weights", "sequential"},
                  {"landmarks", "0"}}));
  r.add(pfMethod("uwb-pf",
                 "UWB + odometry particle filter (the UWB single-sensor particle baseline), "
                 "NLOS test against the odometry-predicted pose",
                 {"odometry", "ranges"}, false, true, {{"nlos", "lidar"}, {"landmarks", "0"}}));
}

}  // namespace uwbloc::loc
