// Every registered method through one suite: convergence on synthetic data with fixed seeds,
// bad measurements rejected and counted, no NaN out, and the registry's errors.
#include <gtest/gtest.h>

#include <limits>

#include "synthetic.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/localization/registry.hpp"

using namespace uwbloc;

struct Case {
  std::string spec;
  double max_rmse;  ///< 2D RMSE bound on the synthetic loop [m]
};

class EveryMethod : public ::testing::TestWithParam<Case> {};

TEST_P(EveryMethod, ConvergesOnSyntheticLoop) {
  const Case c = GetParam();
  const data::Dataset ds = test::makeSquareLoop(3);
  const auto run = eval::runMethod(ds, c.spec, 3);
  const auto errors = eval::associate(run.trajectory, ds.ground_truth);
  const auto m = eval::computeMetrics(errors, run.trajectory, ds.ground_truth);
  EXPECT_GT(m.coverage, 0.95) << c.spec;
  EXPECT_LT(m.rmse_2d, c.max_rmse) << c.spec;
  std::printf("[ SYNTH    ] %-10s rmse_2d %.4f m, %ld steps\n", c.spec.c_str(), m.rmse_2d, m.steps);
}

TEST_P(EveryMethod, RejectsBadMeasurementsAndNeverEmitsNaN) {
  const Case c = GetParam();
  data::Dataset ds = test::makeSquareLoop(5, 0.1, 30.0);
  // Corrupt the stream: NaN, zero, negative, absurd ranges, an unknown anchor, time going back.
  std::vector<loc::Event> bad;
  int i = 0;
  for (const auto& e : ds.events) {
    bad.push_back(e);
    if (const auto* r = std::get_if<uwb::Range>(&e); r && ++i % 10 == 0) {
      uwb::Range x = *r;
      const int kind = (i / 10) % 6;
      if (kind == 0) x.range = std::numeric_limits<double>::quiet_NaN();
      if (kind == 1) x.range = 0.0;
      if (kind == 2) x.range = -2.0;
      if (kind == 3) x.range = 1e6;
      if (kind == 4) x.anchor_id = 99;
      if (kind == 5) x.t -= 5.0;
      bad.emplace_back(x);
    }
    if (const auto* o = std::get_if<loc::OdometryIncrement>(&e); o && i % 50 == 0) {
      loc::OdometryIncrement x = *o;
      x.delta.x() = std::numeric_limits<double>::quiet_NaN();
      bad.emplace_back(x);
    }
  }
  ds.events = bad;
  const auto run = eval::runMethod(ds, c.spec, 5);
  for (const auto& p : run.trajectory) {
    ASSERT_TRUE(p.pose.allFinite()) << c.spec << " at t=" << p.t;
    ASSERT_TRUE(p.covariance.allFinite()) << c.spec << " at t=" << p.t;
  }
  const auto& rej = run.statistics.rejected;
  if (c.spec == "odom" || c.spec == "graph-uwb-odom") {
    EXPECT_GT(rej.count("non_finite_odometry"), 0u);
  }
  if (c.spec == "odom") {
    EXPECT_GT(rej.count("non_finite_odometry"), 0u);
  } else {
    for (const char* reason : {"non_finite", "zero_range", "negative_range", "beyond_max_range",
                               "unknown_anchor", "time_backwards"})
      EXPECT_GT(rej.count(reason), 0u) << c.spec << " did not count " << reason;
  }
  const auto errors = eval::associate(run.trajectory, ds.ground_truth);
  EXPECT_LT(eval::computeMetrics(errors, run.trajectory, ds.ground_truth).rmse_2d, c.max_rmse * 1.5)
      << c.spec;
}

INSTANTIATE_TEST_SUITE_P(Registry, EveryMethod,
                         ::testing::Values(Case{"uwb-ls", 0.15}, Case{"uwb-gn", 0.15},
                                           Case{"uwb-chan", 0.15}, Case{"uwb-kf", 0.12},
                                           Case{"uwb-ekf", 0.10}, Case{"odom", 1e-6},
                                           Case{"graph-uwb-odom", 0.05}),
                         [](const auto& info) {
                           std::string n = info.param.spec;
                           for (auto& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

TEST(Registry, ListsEveryMethodWithDefaults) {
  const auto& reg = loc::Registry::builtin();
  for (const char* name : {"uwb-ls", "uwb-gn", "uwb-chan", "uwb-kf", "uwb-ekf", "odom"}) {
    const auto* m = reg.find(name);
    ASSERT_NE(m, nullptr) << name;
    EXPECT_FALSE(m->description.empty());
  }
  const auto* ekf = reg.find("uwb-ekf");
  bool has_q = false;
  for (const auto& p : ekf->defaults) has_q |= p.key == "q" && p.value == "0.1";
  EXPECT_TRUE(has_q);
}

TEST(Registry, SpecOverridesAndEffectiveParameters) {
  loc::EstimatorContext ctx;
  ctx.anchors = {{1, {0, 0, 0}}};
  const auto est = loc::Registry::builtin().create("uwb-kf:q=0.25,solver=gn", ctx);
  EXPECT_EQ(est->name(), "uwb-kf");
  std::map<std::string, std::string> eff;
  for (const auto& p : est->parameters()) eff[p.key] = p.value;
  EXPECT_EQ(eff["q"], "0.25");
  EXPECT_EQ(eff["solver"], "gn");
  // A config-file value is overridden by the spec.
  loc::ParamSet extra;
  extra.set("q", "0.9");
  extra.set("sigma", "0.3");
  const auto est2 = loc::Registry::builtin().create("uwb-kf:q=0.25", ctx, extra);
  for (const auto& p : est2->parameters()) eff[p.key] = p.value;
  EXPECT_EQ(eff["q"], "0.25");
  EXPECT_EQ(eff["sigma"], "0.3");
}

TEST(Registry, ErrorsNameTheProblem) {
  loc::EstimatorContext ctx;
  auto message = [&](const std::string& spec) {
    try {
      loc::Registry::builtin().create(spec, ctx);
    } catch (const loc::ParamError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("uwb-magic").find("unknown method 'uwb-magic'"), std::string::npos);
  EXPECT_NE(message("uwb-kf:qq=1").find("unknown parameter(s) qq"), std::string::npos);
  EXPECT_NE(message("uwb-kf:q=abc").find("'q' has invalid value 'abc'"), std::string::npos);
  EXPECT_NE(message("uwb-kf:q").find("expected key=value"), std::string::npos);
  EXPECT_NE(message("uwb-kf:solver=svd").find("solver"), std::string::npos);
  EXPECT_NE(message("uwb-ekf:iq=maybe").find("boolean"), std::string::npos);
}
