// Particle-filter core: resamplers, estimate on the circle, degenerate weights, motion model,
// and the likelihood field.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "uwbloc/dataset/world.hpp"
#include "uwbloc/localization/lidar/likelihood_field.hpp"
#include "uwbloc/localization/pf/particle_filter.hpp"
#include "uwbloc/localization/range_mixture.hpp"

using namespace uwbloc::loc;

class Resamplers : public ::testing::TestWithParam<ResamplerKind> {
 protected:
  const std::vector<double> w{0.30, 0.05, 0.15, 0.0, 0.25, 0.01, 0.09, 0.05, 0.06, 0.04};

  // Draws m indices from `w` `trials` times with the resampler under test; checks every index
  // is in range and that E[copies of i] = m w_i within 4.5 standard errors (the multinomial
  // variance m w (1 - w) bounds the other schemes'). Returns the copies of each particle.
  std::vector<double> expectUnbiased(size_t m, int trials, uint64_t seed) {
    auto resampler = makeResampler(GetParam());
    Rng rng(seed);
    std::vector<int> idx(m);
    std::vector<double> copies(w.size(), 0.0);
    for (int t = 0; t < trials; ++t) {
      std::fill(idx.begin(), idx.end(), -1);
      EXPECT_TRUE(resampler->selectIndices(w, idx, rng));
      for (int i : idx) {
        EXPECT_GE(i, 0);
        EXPECT_LT(i, static_cast<int>(w.size()));
        if (i >= 0 && i < static_cast<int>(w.size())) copies[static_cast<size_t>(i)] += 1.0;
      }
    }
    for (size_t i = 0; i < w.size(); ++i) {
      const double se = std::sqrt(m * w[i] * (1 - w[i]) / trials) + 1e-9;
      EXPECT_NEAR(copies[i] / trials, m * w[i], 4.5 * se + 1e-12)
          << enumName(GetParam()) << " " << i;
    }
    return copies;
  }
};

TEST_P(Resamplers, KeepTheCountAndAreUnbiased) {
  // n draws from n weights, 4000 seeded trials; a zero-weight particle is never drawn.
  const auto copies = expectUnbiased(w.size(), 4000, 17);
  EXPECT_EQ(copies[3], 0.0) << "a zero-weight particle was drawn";
}

TEST_P(Resamplers, DrawFewerThanTheyAreGivenWithoutBias) {
  // Shrinking a wide start: 4 draws from 10 weights, 8000 seeded trials.
  expectUnbiased(4, 8000, 5);
}

INSTANTIATE_TEST_SUITE_P(All, Resamplers,
                         ::testing::Values(ResamplerKind::kMultinomial, ResamplerKind::kSystematic,
                                           ResamplerKind::kStratified, ResamplerKind::kResidual),
                         [](const auto& info) { return std::string(enumName(info.param)); });

TEST(ParticleFilter, UnknownResamplerIsAnErrorListingTheKnownOnes) {
  ParamSet set = ParamSet::parse("resampler=ibas", "method 'pf-sir'");
  ResamplerKind kind = ResamplerKind::kSystematic;
  try {
    set.read("resampler", kind);
    ADD_FAILURE() << "no error for an unknown resampler";
  } catch (const ParamError& e) {
    const std::string what = e.what();
    for (const char* part : {"pf-sir", "resampler", "ibas", "multinomial", "residual"})
      EXPECT_NE(what.find(part), std::string::npos) << what;
  }
}

TEST(ParticleFilter, EstimateAveragesTheAngleOnTheCircle) {
  ParticleFilterParams p;
  p.particles = 2;
  ParticleFilter pf(p, makeResampler(ResamplerKind::kSystematic), 1);
  pf.initGaussian({0, 0, 0}, {0, 0, 0});
  auto& s = pf.particles();
  s.x = {1.0, 3.0};
  s.y = {0.0, 2.0};
  s.theta = {M_PI - 0.1, -M_PI + 0.1};
  pf.normalizeAndResample();  // equal weights: ESS = N, no resampling
  const auto e = pf.estimate();
  EXPECT_NEAR(e.mean.x(), 2.0, 1e-12);
  EXPECT_NEAR(e.mean.y(), 1.0, 1e-12);
  EXPECT_NEAR(std::abs(e.mean.z()), M_PI, 1e-12);  // not 0
  EXPECT_NEAR(e.covariance(2, 2), 0.01, 1e-12);
  EXPECT_NEAR(e.covariance(0, 0), 1.0, 1e-12);
}

TEST(ParticleFilter, DegenerateWeightsStayFiniteAndNormalised) {
  ParticleFilterParams p;
  p.particles = 50;
  ParticleFilter pf(p, makeResampler(ResamplerKind::kResidual), 3);
  pf.initGaussian({1, 2, 0.5}, {0.1, 0.1, 0.1});
  pf.weight([](double, double, double) { return -std::numeric_limits<double>::infinity(); });
  pf.weight([](double, double, double) { return std::nan(""); });
  pf.normalizeAndResample();
  double sum = 0.0;
  for (double w : pf.weights()) {
    ASSERT_TRUE(std::isfinite(w));
    sum += w;
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_TRUE(pf.estimate().mean.allFinite());
}

TEST(ParticleFilter, ResamplesOnlyBelowTheEssThreshold) {
  ParticleFilterParams p;
  p.particles = 100;
  p.ess_threshold = 0.5;
  ParticleFilter pf(p, makeResampler(ResamplerKind::kSystematic), 5);
  pf.initGaussian({0, 0, 0}, {1, 1, 0.1});
  pf.weight([](double x, double, double) { return -0.01 * x * x; });  // mild: ESS stays high
  EXPECT_FALSE(pf.normalizeAndResample());
  pf.weight([](double x, double, double) { return -50.0 * x * x; });  // sharp
  EXPECT_TRUE(pf.normalizeAndResample());
  EXPECT_EQ(pf.particles().size(), 100u);
  EXPECT_LT(std::abs(pf.estimate().mean.x()), 0.1);
}

// The marginal likelihood of the measurements: a prior N(0, 1) on x and a measurement z = x + v,
// v ~ N(0, 0.5^2), give p(z) = N(z; 0, 1.25), whatever the weights' normalisation; a likelihood
// that is the same at every particle adds its own log, before and after a resampling.
TEST(ParticleFilter, LogEvidenceIsTheMeasurementsMarginalLikelihood) {
  ParticleFilterParams p;
  p.particles = 200000;
  p.ess_threshold = 1.0;  // resample after any uneven weighting
  ParticleFilter pf(p, makeResampler(ResamplerKind::kSystematic), 7);
  pf.initGaussian({0, 0, 0}, {1, 1, 0.1});
  EXPECT_EQ(pf.logEvidence(), 0.0);
  const double z = 0.8, r = 0.5, s2 = 1.0 + r * r;
  pf.weight([&](double x, double, double) {
    return -0.5 * (z - x) * (z - x) / (r * r) - std::log(r * std::sqrt(2.0 * M_PI));
  });
  EXPECT_TRUE(pf.normalizeAndResample());
  const double analytic = -0.5 * z * z / s2 - 0.5 * std::log(2.0 * M_PI * s2);
  EXPECT_NEAR(pf.logEvidence(), analytic, 0.01);
  const double first = pf.logEvidence();
  pf.weight([](double, double, double) { return -2.0; });
  pf.normalize();
  EXPECT_NEAR(pf.logEvidence() - first, -2.0, 1e-9);
  pf.normalize();  // nothing weighed since: nothing added
  EXPECT_NEAR(pf.logEvidence() - first, -2.0, 1e-9);
  pf.resetEvidence();
  EXPECT_EQ(pf.logEvidence(), 0.0);
}

TEST(ParticleFilter, MotionModelMovesTheCloudByTheIncrement) {
  ParticleFilterParams p;
  p.particles = 4000;
  ParticleFilter pf(p, makeResampler(ResamplerKind::kSystematic), 9);
  pf.initGaussian({1.0, 1.0, M_PI / 2}, {0, 0, 0});
  for (int i = 0; i < 10; ++i) pf.predict({0.1, 0.0, 0.0});  // 1 m forward, facing +y
  pf.normalizeAndResample();
  const auto e = pf.estimate();
  EXPECT_NEAR(e.mean.x(), 1.0, 0.01);
  EXPECT_NEAR(e.mean.y(), 2.0, 0.01);
  EXPECT_NEAR(e.mean.z(), M_PI / 2, 0.01);
  EXPECT_GT(e.covariance(1, 1), 0.0);  // noise grew with the motion
}

TEST(LikelihoodField, DistancesAndPeakAtTheTruePose) {
  const auto map = uwbloc::data::mapFromRectangles({0, 0, 10, 6}, {{4, 2, 5, 3}}, 0.05);
  LikelihoodFieldParams params;
  params.max_dist = 1.0;
  params.decimation = 4;
  LikelihoodField field(map, params);
  EXPECT_NEAR(field.distance(2.0, 0.5), 0.5, 0.06);  // to the wall y = 0
  EXPECT_NEAR(field.distance(4.5, 3.4), 0.4, 0.06);  // above the obstacle
  EXPECT_NEAR(field.distance(2.0, 3.0), 1.0, 1e-9);  // capped
  const Eigen::Vector3d truth(2.0, 2.5, 0.3);
  field.setScan(uwbloc::data::castScan(map, truth, uwbloc::data::LidarParams::preset("sick_lms")));
  ASSERT_GT(field.rays(), 50u);
  const double at_truth = field.logLikelihood(truth.x(), truth.y(), truth.z());
  for (const Eigen::Vector3d& d :
       {Eigen::Vector3d(0.2, 0, 0), Eigen::Vector3d(0, -0.2, 0), Eigen::Vector3d(0, 0, 0.1)})
    EXPECT_GT(at_truth,
              field.logLikelihood(truth.x() + d.x(), truth.y() + d.y(), truth.z() + d.z()));
}

TEST(LikelihoodField, TablesAreSharedPerLiveMapAndModel) {
  const auto rooms = [](double obstacle_x) {
    return std::make_shared<const uwbloc::loc::OccupancyMap>(
        uwbloc::data::mapFromRectangles({0, 0, 10, 6}, {{obstacle_x, 2, obstacle_x + 1, 3}}, 0.05));
  };
  LikelihoodFieldParams params;
  params.max_dist = 1.0;
  params.decimation = 4;
  auto map = rooms(4.0);
  const LikelihoodField a(map, params), b(map, params);
  EXPECT_TRUE(a.sharesTables(b));
  auto every_ray = params;  // the decimation is not part of the tables
  every_ray.decimation = 1;
  EXPECT_TRUE(a.sharesTables(LikelihoodField(map, every_ray)));
  auto wider = params;
  wider.sigma_hit = 0.5;
  EXPECT_FALSE(a.sharesTables(LikelihoodField(map, wider)));
  // The same scores as tables built for one field alone.
  LikelihoodField shared(map, params), alone(*map, params);
  EXPECT_FALSE(shared.sharesTables(alone));
  const Eigen::Vector3d truth(2.0, 2.5, 0.3);
  const auto scan =
      uwbloc::data::castScan(*map, truth, uwbloc::data::LidarParams::preset("sick_lms"));
  shared.setScan(scan);
  alone.setScan(scan);
  for (double dx : {0.0, 0.1, 0.3})
    EXPECT_EQ(shared.logLikelihood(truth.x() + dx, truth.y(), truth.z()),
              alone.logLikelihood(truth.x() + dx, truth.y(), truth.z()));
  // A map made after another one died gets its own tables, even at the dead map's address
  // (made here right after the old one is freed, which the allocator is likely to reuse): the
  // obstacle moved from x = 4..5 to x = 7..8.
  auto old_map = rooms(4.0);
  EXPECT_NEAR(LikelihoodField(old_map, params).distance(4.5, 3.4), 0.4, 0.06);
  auto replacement = uwbloc::data::mapFromRectangles({0, 0, 10, 6}, {{7, 2, 8, 3}}, 0.05);
  const auto* old_address = old_map.get();
  old_map.reset();
  const auto new_map = std::make_shared<const uwbloc::loc::OccupancyMap>(std::move(replacement));
  if (new_map.get() == old_address) std::printf("the new map took the old one's address\n");
  const LikelihoodField moved(new_map, params);
  EXPECT_NEAR(moved.distance(4.5, 3.4), 1.0, 1e-9);
  EXPECT_NEAR(moved.distance(7.5, 3.4), 0.4, 0.06);
}

TEST(ParticleFilter, WideStartShrinksOnceConvergedAndGrowsBackOnReset) {
  ParticleFilterParams p;
  p.particles = 50;
  p.initial_particles = 1000;
  ParticleFilter pf(p, makeResampler(ResamplerKind::kSystematic), 3);
  pf.initUniformBox({0, 0, 0}, {2.0, 2.0, M_PI});
  EXPECT_EQ(pf.particles().size(), 1000u);
  // A wide cloud: even with degenerate weights it resamples at its own size.
  pf.weight([](double x, double, double) { return -x * x; });
  pf.normalizeAndResample();
  EXPECT_EQ(pf.particles().size(), 1000u);
  // A sharp measurement of the whole pose: the cloud converges and drops to 50.
  for (int k = 0; k < 3; ++k) {
    pf.weight([](double x, double y, double th) {
      return -(x * x + y * y) / (2 * 0.05 * 0.05) - th * th / (2 * 0.05 * 0.05);
    });
    pf.normalizeAndResample();
  }
  EXPECT_EQ(pf.particles().size(), 50u);
  EXPECT_EQ(pf.weights().size(), 50u);
  // 1000 particles over 4 m x 4 m x 2 pi leave the nearest few some 0.2 m from the truth; the
  // converged cloud is made of copies of them.
  EXPECT_LT(pf.estimate().mean.head<2>().norm(), p.converged_xy);
  pf.initUniformBox({0, 0, 0}, {2.0, 2.0, M_PI});
  EXPECT_EQ(pf.particles().size(), 1000u);
}

// Fox's bound (IJRR 2003, eq. 12): (k - 1) / (2 eps) {1 - 2/(9(k-1)) + sqrt(2/(9(k-1))) z}^3, the
// Wilson-Hilferty form of the chi-square quantile chi2_{k-1, 1-delta} / (2 eps).
TEST(ParticleFilter, KldSampleCountIsFoxsBound) {
  const double z = 2.3263478740408408;  // delta = 0.01
  EXPECT_EQ(kldSampleCount(1.0, 0.05, z), 1.0);
  EXPECT_EQ(kldSampleCount(0.3, 0.05, z), 1.0);
  // Two cells: 10 (7/9 + sqrt(2/9) z)^3.
  EXPECT_NEAR(kldSampleCount(2.0, 0.05, z),
              10.0 * std::pow(7.0 / 9.0 + std::sqrt(2.0 / 9.0) * z, 3), 1e-9);
  EXPECT_NEAR(kldSampleCount(2.0, 0.05, z), 65.858, 1e-3);
  // Against tabulated chi-square 0.99 quantiles: 23.209 (10 degrees), 76.154 (50).
  EXPECT_NEAR(kldSampleCount(11.0, 0.05, z) / (23.209 / 0.1), 1.0, 2e-3);
  EXPECT_NEAR(kldSampleCount(51.0, 0.05, z) / (76.154 / 0.1), 1.0, 5e-4);
  // Half the distance bound, twice the particles.
  EXPECT_NEAR(kldSampleCount(11.0, 0.025, z), 2.0 * kldSampleCount(11.0, 0.05, z), 1e-9);
}

// KLD-sampling: a resampling draws the fewest particles, from n up to n_max, that meet Fox's bound
// over the cells the draw is expected to occupy. A cloud inside one cell keeps n; a wide one draws
// the smallest m with bound(k(m)) <= m, k(m) = sum over cells of 1 - (1 - W_cell)^m; n_max caps it;
// without n_max the count never moves.
TEST(ParticleFilter, KldSamplingDrawsAsManyParticlesAsThePosteriorsSpreadNeeds) {
  ParticleFilterParams p;
  p.particles = 40;
  p.max_particles = 2000;
  p.ess_threshold = 1.5;  // resample at every call
  const auto cellsOf = [&](const ParticleFilter& pf) {
    std::map<std::array<long, 3>, double> cells;
    const auto& s = pf.particles();
    for (size_t i = 0; i < s.size(); ++i)
      cells[{static_cast<long>(std::floor(s.x[i] / p.kld_bin_xy)),
             static_cast<long>(std::floor(s.y[i] / p.kld_bin_xy)),
             static_cast<long>(std::floor(s.theta[i] / p.kld_bin_theta))}] += pf.weights()[i];
    return cells;
  };
  const auto bound = [&](const std::map<std::array<long, 3>, double>& cells, double m) {
    double k = 0.0;
    for (const auto& [cell, mass] : cells) k += 1.0 - std::pow(1.0 - mass, m);
    return std::ceil(kldSampleCount(k, p.kld_epsilon, p.kld_z));
  };

  ParticleFilter pf(p, makeResampler(ResamplerKind::kSystematic), 11);
  pf.initGaussian({0.25, 0.25, 0.08}, {0.02, 0.02, 0.01});  // one cell
  pf.normalize();
  ASSERT_EQ(cellsOf(pf).size(), 1u);
  ASSERT_TRUE(pf.normalizeAndResample());
  EXPECT_EQ(pf.particles().size(), 40u);

  // 40 particles, each in a cell of its own, weighted unevenly: few draws would miss the light
  // cells, so the count is less than with every cell counted.
  pf.initUniformBox({0, 0, 0}, {2.5, 2.5, M_PI});
  pf.weight([](double x, double y, double) { return -(x * x + y * y) / (2 * 0.8 * 0.8); });
  pf.normalize();
  const auto wide = cellsOf(pf);
  ASSERT_GT(wide.size(), 35u);
  ASSERT_TRUE(pf.normalizeAndResample());
  const auto m = static_cast<double>(pf.particles().size());
  EXPECT_LE(bound(wide, m), m);
  EXPECT_GT(bound(wide, m - 1.0), m - 1.0) << "not the fewest that meet the bound";
  EXPECT_GT(m, 100.0);
  EXPECT_LT(m, bound(wide, 1e9)) << "every cell counted, light or not";
  EXPECT_EQ(pf.weights().size(), pf.particles().size());
  EXPECT_EQ(pf.resamplesAboveLeast(), 1);
  EXPECT_EQ(pf.mostDrawn(), pf.particles().size());

  // Converged again: back to n.
  for (int k = 0; k < 3; ++k) {
    pf.weight([](double x, double y, double th) {
      return -((x - 0.25) * (x - 0.25) + (y - 0.25) * (y - 0.25)) / (2 * 0.02 * 0.02) -
             (th - 0.08) * (th - 0.08) / (2 * 0.01 * 0.01);
    });
    pf.normalizeAndResample();
  }
  EXPECT_EQ(pf.particles().size(), 40u);

  // The cap, and no adaptation without it.
  for (int most : {300, 0}) {
    ParticleFilterParams q = p;
    q.max_particles = most;
    ParticleFilter capped(q, makeResampler(ResamplerKind::kSystematic), 11);
    capped.initUniformBox({0, 0, 0}, {2.5, 2.5, M_PI});
    ASSERT_TRUE(capped.normalizeAndResample());
    EXPECT_EQ(capped.particles().size(), most ? 300u : 40u);
  }
}

// ------------------------------------------------------------------ the range-error mixture

TEST(RangeMixture, DensityIsNormalisedAndGaussianWithoutNlos) {
  uwbloc::loc::RangeMixture m;
  m.nlos_fraction = 0.6;
  m.sigma = 0.1;
  m.nlos_mean = 0.5;
  double integral = 0.0, mean = 0.0;
  const double step = 1e-4;
  for (double e = -2.0; e < 12.0; e += step) {
    const double p = std::exp(m.logDensity(e));
    integral += p * step;
    mean += e * p * step;
  }
  EXPECT_NEAR(integral, 1.0, 1e-4);
  EXPECT_NEAR(mean, 0.6 * 0.5, 1e-3);  // the NLOS part's mean excess, in 60 % of the ranges
  // Far in the short tail only the Gaussian parts remain (no underflow to -inf).
  EXPECT_TRUE(std::isfinite(m.logDensity(-30.0)));
  m.nlos_fraction = 1e-9;
  EXPECT_NEAR(m.logDensity(0.2), -0.5 * 4.0 - std::log(0.1 * std::sqrt(2.0 * M_PI)), 1e-6);
}

// P(NLOS | e) is the NLOS part's share of the density at e, with the link's own prior for w:
// the two parts' densities are read off the mixture's density at two values of w (it is linear
// in w), and the posterior is formed from them by Bayes' rule.
TEST(RangeMixture, NlosPosteriorIsBayesRuleWithTheLinksPrior) {
  RangeMixture m;
  m.sigma = 0.1;
  m.nlos_mean = 0.5;
  for (double e : {-0.1, 0.0, 0.15, 0.4, 1.0})
    for (double prior : {0.2, 0.5, 0.8}) {
      const double p0 = std::exp(m.withNlosFraction(0.25).logDensity(e, 0.12));
      const double p1 = std::exp(m.withNlosFraction(0.75).logDensity(e, 0.12));
      // p(w) = (1 - w) N + w E at w = 0.25 and 0.75.
      const double nlos = 1.5 * p1 - 0.5 * p0, los = 1.5 * p0 - 0.5 * p1;
      const double expected = prior * nlos / (prior * nlos + (1.0 - prior) * los);
      EXPECT_NEAR(m.nlosPosterior(e, 0.12, prior), expected, 1e-9) << e << " " << prior;
    }
  EXPECT_GT(m.nlosPosterior(1.5, 0.1, 0.5), 0.999);  // far longer than the LOS noise explains
  EXPECT_LT(m.nlosPosterior(-0.3, 0.1, 0.5), 0.1);   // shorter than the distance: LOS
  EXPECT_NEAR(m.withNlosFraction(1.0).nlos_fraction, 0.99, 1e-12);  // the LOS part keeps 1 %
  EXPECT_NEAR(m.withNlosFraction(0.0).nlos_fraction, 0.01, 1e-12);
}

// A link's chance of NLOS: the mixture's w until it is seen, then its last posterior relaxed
// toward w with the memory's time constant; each anchor-tag link on its own.
TEST(RangeMixture, TheLinksNlosStateRelaxesTowardTheMixturesShare) {
  NlosStateTrack track(5.0);
  EXPECT_TRUE(track.enabled());
  EXPECT_FALSE(NlosStateTrack(0.0).enabled());
  const double w = 0.8;
  EXPECT_EQ(track.prior(1, 0, 10.0, w), w);
  track.update(1, 0, 10.0, 0.1);
  EXPECT_NEAR(track.prior(1, 0, 10.0, w), 0.1, 1e-12);
  EXPECT_NEAR(track.prior(1, 0, 15.0, w), w + (0.1 - w) * std::exp(-1.0), 1e-12);
  EXPECT_NEAR(track.prior(1, 0, 1e6, w), w, 1e-12);
  EXPECT_NEAR(track.prior(1, 0, 9.0, w), 0.1, 1e-12);  // a range stamped earlier: no decay
  EXPECT_EQ(track.prior(1, 1, 10.0, w), w);            // another tag
  EXPECT_EQ(track.prior(2, 0, 10.0, w), w);            // another anchor
  track.clear();
  EXPECT_EQ(track.prior(1, 0, 10.0, w), w);
}

// Each link's NLOS state from its other ranges (nlosStatePriors). Three links at 10 Hz for
// 600 s, LOS noise 0.05 m, NLOS excess exponential with mean 0.5 m: link 1 in sight all along,
// link 2 out of sight in 30 s stretches (every other one), link 3 out of sight 80 % of the time
// in 10 s stretches. The priors then read each link's state, the memory lies between the
// ranges' spacing and the stretches, and the state predicts better than one fraction. Where
// NLOS strikes each range independently (w = 0.4 for all), the state predicts no better: the
// priors stay near w, or none are returned.
TEST(RangeMixture, EachLinksNlosStateIsReadFromItsNeighboursInTime) {
  std::mt19937 rng(17);
  std::normal_distribution<double> noise(0.0, 0.05);
  std::exponential_distribution<double> excess(1.0 / 0.5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto samples = [&](auto nlos) {
    std::vector<NlosSample> out;
    for (int k = 0; k < 6000; ++k)
      for (int link = 1; link <= 3; ++link) {
        const double t = 0.1 * k + 0.01 * link;
        out.push_back({link, 0, t, noise(rng) + (nlos(link, t) ? excess(rng) : 0.0), 0.05});
      }
    return out;
  };
  std::vector<bool> stretch3(60);
  for (auto&& s : stretch3) s = u(rng) < 0.8;
  auto persistent = [&](int link, double t) {
    if (link == 1) return false;
    if (link == 2) return static_cast<int>(t / 30.0) % 2 == 1;
    return static_cast<bool>(stretch3[static_cast<size_t>(t / 10.0)]);
  };
  auto data = samples(persistent);
  double share = 0.0;
  for (const auto& s : data) share += persistent(s.anchor, s.t) ? 1.0 : 0.0;
  share /= static_cast<double>(data.size());
  RangeMixture m;
  m.sigma = 0.05;
  m.nlos_mean = 0.5;
  m.nlos_fraction = share;
  const auto state = nlosStatePriors(m, data);
  ASSERT_TRUE(state);
  EXPECT_GE(state->memory, 0.5);
  EXPECT_LE(state->memory, 16.0);
  EXPECT_GT(state->log_likelihood_gain, 0.05);
  ASSERT_EQ(state->priors.size(), data.size());
  // Within each stretch (away from its ends) the prior reads the link's state.
  std::map<std::pair<int, bool>, std::vector<double>> by_state;
  for (size_t i = 0; i < data.size(); ++i) {
    const double phase = std::fmod(data[i].t, 10.0);
    if (phase < 2.0 || phase > 8.0) continue;
    by_state[{data[i].anchor, persistent(data[i].anchor, data[i].t)}].push_back(state->priors[i]);
  }
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  std::printf(
      "[ STATE    ] memory %.3g s, gain %.3f per range; median priors: link 1 %.3f, "
      "link 2 LOS %.3f NLOS %.3f, link 3 LOS %.3f NLOS %.3f (w %.3f)\n",
      state->memory, state->log_likelihood_gain, median(by_state[{1, false}]),
      median(by_state[{2, false}]), median(by_state[{2, true}]), median(by_state[{3, false}]),
      median(by_state[{3, true}]), share);
  // The posteriors are soft (an NLOS range a little long looks LOS: about a fifth of them here),
  // so a stretch's mean reads near 0.8, not 1.
  EXPECT_LT(median(by_state[{1, false}]), 0.2);
  EXPECT_LT(median(by_state[{2, false}]), 0.2);
  EXPECT_GT(median(by_state[{2, true}]), 0.7);
  EXPECT_LT(median(by_state[{3, false}]), 0.3);
  EXPECT_GT(median(by_state[{3, true}]), 0.7);

  // Independent NLOS: nothing, or priors near w.
  auto independent = [&](int, double) { return u(rng) < 0.4; };
  m.nlos_fraction = 0.4;
  if (const auto none = nlosStatePriors(m, samples(independent))) {
    EXPECT_LT(none->log_likelihood_gain, 1e-3);
    for (double p : none->priors) EXPECT_NEAR(p, 0.4, 0.1);
  }
  // Too few ranges: nothing.
  data.resize(99);
  EXPECT_FALSE(nlosStatePriors(m, data));
}

// The graph's range residual under the mixture: f^2 / 2 is the negative log-density (with its
// floor) up to a constant, f is zero at the density's mode and increases through it, its slope
// agrees with central differences, and a range far shorter than the distance stops pulling.
TEST(RangeMixture, GraphResidualIsTheRootOfTheNegativeLogDensity) {
  RangeMixture m;
  m.nlos_fraction = 0.4;
  m.sigma = 0.1;
  m.nlos_mean = 0.5;
  const uwbloc::loc::MixtureResidual f(m, 0.12);
  EXPECT_NEAR(f(f.mode()), 0.0, 1e-6);
  EXPECT_GT(f.mode(), 0.0);  // the NLOS excess moves the mode to longer ranges
  EXPECT_LT(f.mode(), 0.12);
  // 0.5 (f(a)^2 - f(b)^2) = log q(b) - log q(a), q = p + the floor, the LOS part's density 4
  // stds out.
  const double floor = 0.6 * std::exp(-8.0) / (0.12 * std::sqrt(2.0 * M_PI));
  const auto log_q = [&](double e) { return std::log(std::exp(m.logDensity(e, 0.12)) + floor); };
  for (const double a : {-0.3, -0.1, 0.05, 0.4, 1.0})
    for (const double b : {-0.2, 0.2, 0.8}) {
      const double expected = log_q(b) - log_q(a);
      EXPECT_NEAR(0.5 * (f(a) * f(a) - f(b) * f(b)), expected, 1e-6) << a << " " << b;
    }
  double previous = -1e9;
  for (double e = -0.6; e < 3.0; e += 0.01) {
    double slope = 0.0;
    const double v = f(e, &slope);
    const double h = 1e-6;
    EXPECT_NEAR(slope, (f(e + h) - f(e - h)) / (2.0 * h), 1e-4 * std::max(1.0, slope)) << e;
    EXPECT_GE(slope, 0.0) << e;
    EXPECT_GT(v, previous) << e;
    previous = v;
  }
  // Short by 6 stds, beyond the floor at 4: no pull left; long by 1 m, still a pull.
  double slope = 1.0;
  f(-0.72, &slope);
  EXPECT_LT(slope, 1e-3);
  f(1.0, &slope);
  EXPECT_GT(slope, 0.5);
}

namespace {
/// Residuals of three anchors: LOS N(0, 0.1), a share `w` of them long by Exp(mean 0.5); the
/// third anchor's shifted by `bias3`.
std::vector<std::pair<int, double>> mixtureResiduals(double w, double bias3, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.1);
  std::exponential_distribution<double> excess(1.0 / 0.5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<std::pair<int, double>> out;
  for (int i = 0; i < 3000; ++i) {
    const int anchor = 1 + i % 3;
    double e = noise(rng) + (anchor == 3 ? bias3 : 0.0);
    if (u(rng) < w) e += excess(rng);
    out.emplace_back(anchor, e);
  }
  return out;
}
}  // namespace

TEST(RangeMixture, FitRecoversTheNlosShareTheExcessAndTheNoise) {
  const auto fit = uwbloc::loc::fitRangeMixture(mixtureResiduals(0.6, 0.0, 7));
  ASSERT_TRUE(fit);
  EXPECT_NEAR(fit->mixture.nlos_fraction, 0.6, 0.05);
  EXPECT_NEAR(fit->mixture.nlos_mean, 0.5, 0.05);
  EXPECT_NEAR(fit->mixture.sigma, 0.1, 0.015);
  EXPECT_NEAR(fit->offset, 0.0, 0.02);
  EXPECT_GT(fit->log_likelihood, fit->biased_gaussian_log_likelihood);
}

TEST(RangeMixture, MeansPerAnchorPayForTheirParameters) {
  // Six anchors seen from a pose that is itself a little off (the LiDAR's, while it settles):
  // each anchor's residuals shifted by up to 0.29 m, 66 % of them long by an exponential
  // excess, 1680 ranges. A Gaussian with a mean per anchor then fits a little better per
  // residual than the mixture (-0.5819 against -0.5852), but its 7 parameters against the
  // mixture's 4 cost more than that (BIC: 3 ln(1680) / 2 / 1680 = 0.0066 per residual).
  const std::vector<double> shifts{-0.2875, 0.1725, 0.2875, -0.1725, 0.23, -0.23};
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  std::exponential_distribution<double> excess(1.0 / 0.45);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<std::pair<int, double>> residuals;
  for (int i = 0; i < 1680; ++i) {
    const auto a = static_cast<size_t>(i % 6);
    residuals.emplace_back(static_cast<int>(a) + 1,
                           shifts[a] + noise(rng) + (u(rng) < 0.66 ? excess(rng) : 0.0));
  }
  const auto fit = uwbloc::loc::fitRangeMixture(residuals);
  ASSERT_TRUE(fit);
  std::printf("[ MIXTURE  ] per residual: mixture %.4f, Gaussian %.4f, mean per anchor %.4f\n",
              fit->log_likelihood, fit->gaussian_log_likelihood,
              fit->biased_gaussian_log_likelihood);
  EXPECT_LT(fit->log_likelihood, fit->biased_gaussian_log_likelihood);
  EXPECT_NEAR(fit->mixture.nlos_mean, 0.45, 0.15);
}

// The integrated autocorrelation time against its analytic values: 1 for white noise, and
// (1 + a) / (1 - a) for an AR(1) series x_k = a x_{k-1} + w_k (a = 0.8: 9, a = 0.5: 3).
TEST(RangeMixture, AutocorrelationTimeOfWhiteAndAr1Series) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  const auto ar1 = [&](double a, size_t n) {
    std::vector<double> x(n);
    double v = 0.0;
    for (auto& e : x) e = v = a * v + g(rng);
    return x;
  };
  const double white = uwbloc::loc::integratedAutocorrelationTime(ar1(0.0, 100000));
  const double half = uwbloc::loc::integratedAutocorrelationTime(ar1(0.5, 100000));
  const double slow = uwbloc::loc::integratedAutocorrelationTime(ar1(0.8, 100000));
  std::printf("[ TAU      ] white %.3f (1), AR(1) 0.5 %.3f (3), AR(1) 0.8 %.3f (9)\n", white, half,
              slow);
  EXPECT_NEAR(white, 1.0, 0.1);
  EXPECT_NEAR(half, 3.0, 0.3);
  EXPECT_NEAR(slow, 9.0, 0.9);
  // Too short, or constant: 1.
  EXPECT_EQ(uwbloc::loc::integratedAutocorrelationTime(ar1(0.8, 19)), 1.0);
  EXPECT_EQ(uwbloc::loc::integratedAutocorrelationTime(std::vector<double>(100, 2.0)), 1.0);
}

TEST(RangeMixture, GaussianResidualsAndABiasedAnchorAreNotNlos) {
  // Gaussian noise: the mixture is not worth its parameters.
  EXPECT_FALSE(uwbloc::loc::fitRangeMixture(mixtureResiduals(0.0, 0.0, 7)));
  // One anchor 1 m long: a skew over all ranges, but a mean per anchor explains it.
  EXPECT_FALSE(uwbloc::loc::fitRangeMixture(mixtureResiduals(0.0, 1.0, 7)));
  // Too few residuals to judge.
  auto few = mixtureResiduals(0.6, 0.0, 7);
  few.resize(90);
  EXPECT_FALSE(uwbloc::loc::fitRangeMixture(few));
}
