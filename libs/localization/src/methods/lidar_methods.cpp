// Registration of the LiDAR-based methods.
#include "uwbloc/localization/methods/lidar_icp.hpp"
#include "uwbloc/localization/methods/pf_localizer.hpp"
#include "uwbloc/localization/registry.hpp"

namespace uwbloc::loc {

namespace {

MethodInfo pfMethod(const std::string& name, const std::string& description,
                    std::vector<std::string> needs, bool lidar, bool uwb, const std::string& nlos) {
  auto info = makeMethod<PfLocalizer, PfLocalizerParams>(
      name, description, std::move(needs),
      [lidar, uwb](const PfLocalizerParams& p, const EstimatorContext& ctx) {
        return std::make_unique<PfLocalizer>(p, ctx, lidar, uwb);
      });
  // Method-specific defaults differ from the struct's; patch them into the description and the
  // factory alike by pre-setting them.
  auto make = info.make;
  info.make = [make, nlos](ParamSet& set, const EstimatorContext& ctx) {
    if (!set.has("nlos")) set.set("nlos", nlos);
    return make(set, ctx);
  };
  for (auto& d : info.defaults)
    if (d.key == "nlos") d.value = nlos;
  return info;
}

}  // namespace

void addLidarMethods(Registry& r) {
  r.add(makeMethod<LidarIcp, LidarIcpParams>(
      "lidar-icp", "LiDAR odometry: scan-to-scan ICP seeded by odometry, from the start pose",
      {"scans"}));
  r.add(pfMethod("lidar-mcl", "LiDAR only: Monte-Carlo localisation on the map's likelihood field",
                 {"scans", "odometry", "map"}, true, false, "none"));
  r.add(pfMethod("fused-naive",
                 "LiDAR + UWB particle filter, likelihoods multiplied, no NLOS rejection",
                 {"scans", "odometry", "map", "ranges"}, true, true, "none"));
  r.add(pfMethod("fused-pf", "LiDAR + UWB particle filter with NLOS rejection from the LiDAR pose",
                 {"scans", "odometry", "map", "ranges"}, true, true, "lidar"));
}

}  // namespace uwbloc::loc
