// libFuzzer target: method specs ("name:k=v,k=v") through the registry, as the CLI builds every
// method, and the same text as a --set override ("method.key=value").
#include <cstdint>
#include <cstdlib>
#include <string>

#include "uwbloc/localization/registry.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  uwbloc::loc::EstimatorContext ctx;
  ctx.anchors = {{1, {0, 0, 2}}, {2, {6, 0, 2}}, {3, {0, 6, 2}}};
  ctx.initial_pose = Eigen::Vector3d(1, 1, 0);
  try {
    const auto o = uwbloc::loc::SetOverride::parse(text, uwbloc::loc::Registry::builtin());
    uwbloc::loc::ParamSet set;
    set.set(o.key, o.value);
    uwbloc::loc::Registry::builtin().create(o.method, ctx, set);
  } catch (const uwbloc::loc::ParamError&) {
  } catch (const std::invalid_argument&) {
  }
  // Each spec on a robot with one tag and on one with two (the range filters' pose state).
  for (const bool two_tags : {false, true}) {
    if (two_tags) ctx.robot_tags = {0, 2};
    try {
      auto est = uwbloc::loc::Registry::builtin().create(text, ctx);
      // A legal but large particle count (up to 1e6) takes seconds per range under the
      // sanitizers: parsing and construction are fuzzed, the filter's speed is not.
      for (const auto& p : est->parameters())
        if ((p.key == "n" || p.key == "init_n" || p.key == "relocalise_n") &&
            std::strtod(p.value.c_str(), nullptr) > 1e4)
          return 0;
      for (const int tag : {0, 2}) {
        uwbloc::uwb::Range r;
        r.t = 1.0;
        r.anchor_id = 1;
        r.range = 3.0;
        r.tag_id = tag;
        r.tag_on_robot = Eigen::Vector3d(tag == 0 ? 0.1 : -0.1, 0.1, 1.0);
        est->process(r);
      }
      est->finishAll();
    } catch (const uwbloc::loc::ParamError&) {
    } catch (const std::invalid_argument&) {
    }
  }
  return 0;
}
