// Method registry: maps a spec such as "uwb-kf:q=0.05,sigma=0.1" to a configured estimator, so
// the CLI, the tests and the benchmarks all reach every method the same way.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "uwbloc/localization/estimator.hpp"
#include "uwbloc/localization/params.hpp"

namespace uwbloc::loc {

struct MethodSpec {
  std::string name;  ///< registry name, e.g. "uwb-kf"
  ParamSet params;   ///< overrides from the spec
  std::string text;  ///< the spec as given, used to label the run
  /// Splits "name:k=v,k=v"; throws ParamError on malformed text.
  static MethodSpec parse(const std::string& spec);
};

struct MethodInfo {
  std::string name;
  std::string description;
  /// What a dataset must provide: any of "ranges", "odometry", "scans", "map".
  std::vector<std::string> needs;
  std::vector<ParamInfo> defaults;
  std::function<std::unique_ptr<Estimator>(ParamSet&, const EstimatorContext&)> make;
};

class Registry {
 public:
  /// The registry with every built-in method.
  static const Registry& builtin();

  void add(MethodInfo info);
  const MethodInfo* find(const std::string& name) const;
  const std::vector<MethodInfo>& methods() const { return methods_; }
  std::vector<std::string> names() const;
  /// The names as one comma-separated list, for an error message.
  std::string knownNames() const;

  /// Builds the estimator for `spec`, with `extra` (e.g. from a config file) applied before the
  /// spec's own overrides. Throws ParamError for an unknown method or parameter.
  std::unique_ptr<Estimator> create(const std::string& spec, const EstimatorContext& context,
                                    const ParamSet& extra = {}) const;

 private:
  std::vector<MethodInfo> methods_;
};

/// One `--set` override, "method.key=value" (the method name may hold dots; the last dot before
/// the '=' ends it).
struct SetOverride {
  std::string method, key, value;
  /// Splits the text; throws ParamError for a malformed one, or one whose method is not in
  /// `registry` (the message lists the known methods).
  static SetOverride parse(const std::string& text, const Registry& registry);
};

/// Registration helper: a method whose estimator is constructed as Est(Params, context).
template <class Est, class Params>
MethodInfo makeMethod(
    std::string name, std::string description, std::vector<std::string> needs,
    std::function<std::unique_ptr<Estimator>(const Params&, const EstimatorContext&)> factory =
        nullptr) {
  MethodInfo info;
  info.name = name;
  info.description = std::move(description);
  info.needs = std::move(needs);
  info.defaults = describeParams(Params{});
  info.make = [name, factory](ParamSet& set, const EstimatorContext& ctx) {
    Params params;
    set.setContext("method '" + name + "'");
    if (ctx.range_sigma && !set.has("sigma")) {
      bool has_sigma = false;
      params.visit(
          [&](const char* key, auto&, const char*) { has_sigma |= std::string(key) == "sigma"; });
      if (has_sigma) set.set("sigma", std::to_string(*ctx.range_sigma));
    }
    loadParams(set, params);
    std::unique_ptr<Estimator> est;
    if (factory) {
      est = factory(params, ctx);
    } else if constexpr (std::is_constructible_v<Est, const Params&, const EstimatorContext&>) {
      est = std::make_unique<Est>(params, ctx);
    }
    est->setIdentity(name, describeParams(params));
    return est;
  };
  return info;
}

}  // namespace uwbloc::loc
