// Ceres graph back end: Jacobians of every cost against numeric differentiation, and range SLAM
// on synthetic data (fixed seed): poses, anchor self-calibration, NLOS outliers with a robust loss.
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>

#include "graph/cost_functions.hpp"
#include "uwbloc/dataset/pose_graph_file.hpp"
#include "uwbloc/localization/events.hpp"
#include "uwbloc/localization/graph/range_graph.hpp"
#include "uwbloc/localization/range_noise.hpp"
#include "uwbloc/uwb/range_model.hpp"

using namespace uwbloc;
using namespace uwbloc::loc::graph;
namespace loc = uwbloc::loc;
namespace graph = uwbloc::loc::graph;

namespace {

void checkGradients(const ceres::CostFunction* cost, std::vector<double*> params,
                    const std::vector<const ceres::Manifold*>* manifolds, const char* what) {
  ceres::NumericDiffOptions options;
  ceres::GradientChecker checker(cost, manifolds, options);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(params.data(), 1e-8, &results)) << what << ": " << results.error_log;
}

struct Synthetic {
  std::vector<uwb::Anchor> anchors{{1, {0, 0, 2.0}},
                                   {2, {20, 0, 2.5}},
                                   {3, {20, 15, 1.5}},
                                   {4, {0, 15, 2.0}},
                                   {5, {10, 20, 3.0}}};
  std::vector<Eigen::Vector3d> truth, dead_reckoning;
  std::vector<Eigen::Vector3d> increments;
  std::vector<std::vector<double>> ranges;  // per pose, per anchor
  std::vector<std::vector<bool>> nlos;
  Eigen::Vector3d tag{0.1, 0.0, 1.0};

  Synthetic(uint64_t seed, double nlos_fraction) {
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(0, 1);
    // 200 poses on a closed rounded path, 0.3 m apart.
    for (int k = 0; k < 200; ++k) {
      const double a = 2 * M_PI * k / 200.0;
      truth.emplace_back(10 + 7 * std::cos(a), 8 + 5 * std::sin(a), loc::wrapAngle(a + M_PI / 2));
    }
    dead_reckoning.push_back(truth[0]);
    for (size_t k = 1; k < truth.size(); ++k) {
      Eigen::Vector3d d = loc::relativePose(truth[k - 1], truth[k]);
      d += Eigen::Vector3d(0.02 * g(rng), 0.02 * g(rng), 0.005 * g(rng));
      increments.push_back(d);
      dead_reckoning.push_back(loc::composePose(dead_reckoning.back(), d));
    }
    for (const auto& p : truth) {
      std::vector<double> row;
      std::vector<bool> flags;
      const double c = std::cos(p.z()), s = std::sin(p.z());
      const Eigen::Vector3d t(p.x() + c * tag.x() - s * tag.y(), p.y() + s * tag.x() + c * tag.y(),
                              tag.z());
      for (const auto& a : anchors) {
        const bool bad = u(rng) < nlos_fraction;
        row.push_back((t - a.position).norm() + 0.1 * g(rng) + (bad ? 1.0 : 0.0));
        flags.push_back(bad);
      }
      ranges.push_back(row);
      nlos.push_back(flags);
    }
  }

  RangeGraph graph(const std::vector<uwb::Anchor>& start_anchors) const {
    RangeGraph gr;
    gr.setAnchors(start_anchors);
    for (const auto& p : dead_reckoning) gr.addPose(p);
    for (size_t k = 0; k + 1 < truth.size(); ++k)
      gr.addOdometry(static_cast<int>(k), static_cast<int>(k + 1), increments[k]);
    for (size_t k = 0; k < truth.size(); ++k)
      for (size_t i = 0; i < anchors.size(); ++i)
        gr.addRange(static_cast<int>(k), anchors[i].id, ranges[k][i], tag);
    return gr;
  }

  double poseRmse(const RangeGraph& g) const {
    double s = 0;
    for (size_t k = 0; k < truth.size(); ++k)
      s += (g.pose(k).head<2>() - truth[k].head<2>()).squaredNorm();
    return std::sqrt(s / truth.size());
  }
};

}  // namespace

TEST(GraphCosts, JacobiansMatchNumeric) {
  double pose[3] = {1.2, -0.7, 2.9}, pose2[3] = {1.5, -0.4, -3.0}, anchor[3] = {4.0, 2.0, 2.2},
         bias[1] = {0.3}, scale[1] = {0.07};
  const ceres::AutoDiffManifold<PosePlus, 3, 3> pose_manifold;
  std::unique_ptr<ceres::CostFunction> range(RangeCost::Create(5.1, {0.16, 0.05, 1.1}, 0.1));
  std::vector<const ceres::Manifold*> m1{&pose_manifold, nullptr, nullptr, nullptr};
  checkGradients(range.get(), {pose, anchor, bias, scale}, &m1, "range");
  std::unique_ptr<ceres::CostFunction> rel(
      RelativePoseCost::Create(Eigen::Vector3d(0.3, 0.1, 0.2), Eigen::Vector3d(0.05, 0.05, 0.02)));
  std::vector<const ceres::Manifold*> m2{&pose_manifold, &pose_manifold};
  checkGradients(rel.get(), {pose, pose2}, &m2, "relative pose across +-pi");
  double landmark[2] = {3.0, -2.0};
  std::unique_ptr<ceres::CostFunction> lm(LandmarkCost::Create({1.5, -0.5}, 0.05));
  std::vector<const ceres::Manifold*> m3{&pose_manifold, nullptr};
  checkGradients(lm.get(), {pose, landmark}, &m3, "landmark (eq. 5)");
  std::unique_ptr<ceres::CostFunction> pp(
      PosePriorCost::Create({1.0, -0.5, -3.1}, {0.1, 0.1, 0.05}));
  std::vector<const ceres::Manifold*> m4{&pose_manifold};
  checkGradients(pp.get(), {pose}, &m4, "pose prior across +-pi");
  std::unique_ptr<ceres::CostFunction> prior(PriorCost<3>::Create({4, 2, 2}, {0.5, 0.5, 0.5}));
  checkGradients(prior.get(), {anchor}, nullptr, "prior");
  // Hand-computed range residual: pose at the origin facing +x, tag 0.16 ahead, anchor 3 m
  // ahead at the tag's height: predicted 2.84, measured 3.0, bias 0.06 -> (3 - 2.84 - 0.06)/0.1;
  // with a scale of +5 %: (3 - 1.05 * 2.84 - 0.06) / 0.1 = -0.42.
  double p0[3] = {0, 0, 0}, a0[3] = {3, 0, 1.1}, b0[1] = {0.06}, s0[1] = {0.0}, r = 0;
  const double* ps[4] = {p0, a0, b0, s0};
  range.reset(RangeCost::Create(3.0, {0.16, 0.0, 1.1}, 0.1));
  range->Evaluate(ps, &r, nullptr);
  EXPECT_NEAR(r, 1.0, 1e-12);
  s0[0] = 0.05;
  range->Evaluate(ps, &r, nullptr);
  EXPECT_NEAR(r, -0.42, 1e-12);
  // Constant velocity through three poses 0.2 s and 0.3 s apart: velocities (1, 0) then
  // (0.6/0.3, 0.3/0.3) = (2, 1); change (1, 1) over sqrt(q (0.2 + 0.3) / 2) = 0.5 at q = 1.
  std::unique_ptr<ceres::CostFunction> cv(ConstantVelocityCost::Create(0.2, 0.3, 1.0));
  double ca[3] = {0, 0, 0.4}, cb[3] = {0.2, 0, -2.0}, cc[3] = {0.8, 0.3, 3.1}, rc[2];
  const double* pc[3] = {ca, cb, cc};
  cv->Evaluate(pc, rc, nullptr);
  EXPECT_NEAR(rc[0], 2.0, 1e-12);
  EXPECT_NEAR(rc[1], 2.0, 1e-12);
  std::vector<const ceres::Manifold*> m5{&pose_manifold, &pose_manifold, &pose_manifold};
  checkGradients(cv.get(), {pose, pose2, ca}, &m5, "constant velocity");
}

TEST(GraphCosts, RelativePoseWithAFullInformationMatrix) {
  // r^T r must equal e^T Omega e for a non-diagonal Omega, and the Jacobians must still match.
  Eigen::Matrix3d omega;
  omega << 400, 50, 10, 50, 300, -20, 10, -20, 900;
  const Eigen::Matrix3d l = omega.llt().matrixU();
  const Eigen::Vector3d delta(0.3, 0.1, 0.2);
  std::unique_ptr<ceres::CostFunction> rel(RelativePoseCost::Create(delta, l));
  double a[3] = {0.0, 0.0, 0.0}, b[3] = {0.35, 0.05, 0.25}, r[3];
  const double* ps[2] = {a, b};
  rel->Evaluate(ps, r, nullptr);
  const Eigen::Vector3d e(0.05, -0.05, 0.05);  // b - a in a's frame, minus delta
  EXPECT_NEAR(Eigen::Vector3d(r[0], r[1], r[2]).squaredNorm(), e.dot(omega * e), 1e-9);
  const ceres::AutoDiffManifold<PosePlus, 3, 3> pose_manifold;
  std::vector<const ceres::Manifold*> m{&pose_manifold, &pose_manifold};
  checkGradients(rel.get(), {a, b}, &m, "relative pose, full information");
}

TEST(PoseGraph, ToroAndG2oStoreTheInformationInTheirOwnOrders) {
  // The same matrix [[11 12 13] [12 22 23] [13 23 33]] (values chosen positive definite) in
  // both text forms: TORO's I11 I12 I22 I33 I13 I23 and g2o's I11 I12 I13 I22 I23 I33.
  const auto dir = std::filesystem::temp_directory_path() / "uwbloc_pose_graph_orders";
  std::filesystem::create_directories(dir);
  const auto toro = (dir / "toro.graph").string(), g2o = (dir / "g2o.graph").string();
  std::ofstream(toro) << "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\n"
                         "EDGE2 0 1 1 0 0 100 5 80 50 2 -3\n";
  std::ofstream(g2o) << "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
                        "EDGE_SE2 0 1 1 0 0 100 5 2 80 -3 50\n";
  Eigen::Matrix3d expected;
  expected << 100, 5, 2, 5, 80, -3, 2, -3, 50;
  for (const auto& path : {toro, g2o}) {
    const auto g = uwbloc::data::readPoseGraph2D(path);
    ASSERT_EQ(g.edges.size(), 1u) << path;
    EXPECT_TRUE(g.edges[0].information.isApprox(expected)) << path << "\n"
                                                           << g.edges[0].information;
  }
  std::ofstream(g2o) << "VERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1 0 0 1 5 0 1 0 1\n";
  EXPECT_THROW(uwbloc::data::readPoseGraph2D(g2o), std::exception);  // not positive definite
}

TEST(RangeSlam, RecoversPosesWithFixedAnchors) {
  const Synthetic s(7, 0.0);
  RangeGraph g = s.graph(s.anchors);
  RangeGraphParams params;
  params.loss = graph::RobustLoss::kNone;
  params.odometry_sigma = {0.02, 0.02, 0.005};
  g.build(params);
  const auto sol = g.solve();
  std::printf("[ GRAPH    ] fixed anchors: dead reckoning %.3f m -> %.4f m (%s)\n",
              s.poseRmse(s.graph(s.anchors)), s.poseRmse(g), sol.report.c_str());
  EXPECT_TRUE(sol.usable);
  EXPECT_LT(s.poseRmse(g), 0.05);
  // Marginal covariance of a pose: positive definite, about the size of the errors.
  const auto cov = g.poseCovariance(100);
  ASSERT_TRUE(cov.has_value());
  EXPECT_GT(cov->diagonal().minCoeff(), 0.0);
  EXPECT_LT(std::sqrt(cov->trace()), 0.2);
  const auto all = g.poseCovariances();
  ASSERT_EQ(all.size(), g.poses());
  EXPECT_TRUE(all[100].isApprox(*cov, 1e-6));
  std::printf("[ GRAPH    ] pose 100 std (x, y, theta): %.4f %.4f %.4f\n", std::sqrt((*cov)(0, 0)),
              std::sqrt((*cov)(1, 1)), std::sqrt((*cov)(2, 2)));
}

TEST(RangeSlam, SelectedInversionGivesCeresMarginals) {
  // Every kind of block at once: poses, estimated anchors (the first pose and anchor held),
  // biases, a landmark, and the Cauchy loss over NLOS ranges.
  const Synthetic s(12, 0.1);
  RangeGraph g = s.graph(s.anchors);
  const Eigen::Vector2d mark(12.0, 9.0);
  const int l = g.addLandmark(mark + Eigen::Vector2d(0.3, -0.2));
  for (size_t k : {size_t{5}, size_t{60}, size_t{150}}) {
    const Eigen::Vector3d& p = s.truth[k];
    const double c = std::cos(p.z()), sn = std::sin(p.z());
    const Eigen::Vector2d d = mark - p.head<2>();
    g.addLandmarkObservation(static_cast<int>(k), l,
                             {c * d.x() + sn * d.y(), -sn * d.x() + c * d.y()}, 0.05);
  }
  RangeGraphParams params;
  params.estimate_anchors = true;
  params.estimate_bias = true;
  params.odometry_sigma = {0.02, 0.02, 0.005};
  g.build(params);
  ASSERT_TRUE(g.solve().usable);
  const auto selected = g.poseCovariances();  // marginals.hpp
  ASSERT_EQ(selected.size(), g.poses());
  EXPECT_EQ(selected[0], Eigen::Matrix3d::Zero());  // held
  double worst = 0.0;
  for (size_t k = 1; k < g.poses(); k += 7) {
    const auto ceres_cov = g.poseCovariance(static_cast<int>(k));  // ceres::Covariance
    ASSERT_TRUE(ceres_cov.has_value());
    worst = std::max(worst, (selected[k] - *ceres_cov).norm() / ceres_cov->norm());
  }
  std::printf(
      "[ GRAPH    ] selected inversion against ceres::Covariance: worst relative "
      "difference %.2e\n",
      worst);
  EXPECT_LT(worst, 1e-8);
}

// Ranges 5 % long (a clock error common to the radios), on a field where each anchor is seen
// from 5 to 70 m: with a bias per anchor free (as the scale test reads them), the residuals still
// grow with the distance; the test sees it, and a free scale finds it. A bias of 0.5 m on every
// anchor, which also lengthens every range, is no scale. (Where the robot keeps about the same
// distance to each anchor, as on Synthetic's loop, a scale is a bias per anchor, and the biases
// take it.)
// The ranges alone (motion=cv): a tag under white acceleration of known q, ranged one anchor at
// a time (eight anchors about a 300 m field: the path wanders, as a random-walk velocity does),
// each range its own vertex. The two variance components, started far off (sigma 1 m, q 20),
// settle at the truth: the range std within 10 % and q within 20 % (its edges' redundancy is
// what the ranges and the heading priors leave of the poses' parameters). A pull towards the
// field's centre, tried first, is not white acceleration: q then settles 2.6 times above the
// path's per-step variance, as the model says it should not be compared.
TEST(RangeSlam, ConstantVelocityGraphLearnsRangeNoiseAndMotionQ) {
  std::vector<uwb::Anchor> anchors;
  for (int i = 0; i < 8; ++i) {
    const double a = i * M_PI / 4.0;
    anchors.push_back({i + 1, {150.0 * std::cos(a), 150.0 * std::sin(a), 1.0}});
  }
  const double q = 0.05, sigma = 0.3, dt = 0.25;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0, 1);
  std::vector<Eigen::Vector2d> truth{{0, 0}};
  Eigen::Vector2d v(0.5, 0.2);
  for (int k = 1; k < 800; ++k) {
    truth.push_back(truth.back() + v * dt);
    v += std::sqrt(q * dt) * Eigen::Vector2d(g(rng), g(rng));
  }
  RangeGraph gr;
  gr.setAnchors(anchors);
  for (size_t k = 0; k < truth.size(); ++k) {
    const Eigen::Vector2d start = truth[k] + Eigen::Vector2d(g(rng), g(rng));
    const int p = gr.addPose(Eigen::Vector3d(start.x(), start.y(), 0.0));
    gr.addPosePrior(p, Eigen::Vector3d(start.x(), start.y(), 0.0), {1e4, 1e4, 1.0});
    if (k >= 2) gr.addConstantVelocity(p - 2, p - 1, p, dt, dt);
    const auto& a = anchors[k % anchors.size()];
    const double d = (Eigen::Vector3d(truth[k].x(), truth[k].y(), 0.0) - a.position).norm();
    gr.addRange(p, a.id, d + sigma * g(rng), Eigen::Vector3d::Zero());
  }
  RangeGraphParams params;
  params.loss = RobustLoss::kNone;
  params.range_sigma = 1.0;
  params.accel_psd = 20.0;
  for (int round = 0; round < 30; ++round) {
    gr.build(params);
    ASSERT_TRUE(gr.solve().usable);
    const auto vc = gr.estimateVarianceComponents();
    ASSERT_TRUE(vc.range_sigma && vc.accel_psd);
    params.range_sigma = *vc.range_sigma;
    params.accel_psd = *vc.accel_psd;
  }
  double se = 0;
  for (size_t k = 0; k < truth.size(); ++k) se += (gr.pose(k).head<2>() - truth[k]).squaredNorm();
  std::printf("[ GRAPH    ] ranges alone: sigma %.3f m (true %.2f), q %.4f (true %.2f), rmse %.3f m\n",
              params.range_sigma, sigma, params.accel_psd, q, std::sqrt(se / truth.size()));
  EXPECT_NEAR(params.range_sigma, sigma, 0.1 * sigma);
  EXPECT_NEAR(params.accel_psd, q, 0.2 * q);
}

TEST(RangeSlam, ARangeScaleStandsOutAndIsFound) {
  const std::vector<uwb::Anchor> anchors{
      {1, {0, 0, 1.0}}, {2, {60, 0, 1.0}}, {3, {60, 40, 1.0}}, {4, {0, 40, 1.0}}};
  // A lawn-mower path: 4 rows of 50 m, 1 m apart poses, heading along the row.
  std::vector<Eigen::Vector3d> truth;
  for (int row = 0; row < 4; ++row)
    for (int k = 0; k <= 50; ++k) {
      const bool east = row % 2 == 0;
      truth.emplace_back(east ? 5.0 + k : 55.0 - k, 5.0 + 10.0 * row, east ? 0.0 : M_PI);
    }
  std::mt19937_64 rng(21);
  std::normal_distribution<double> g(0, 1);
  auto build = [&](double scale, double bias) {
    RangeGraph gr;
    gr.setAnchors(anchors);
    Eigen::Vector3d dr = truth[0];
    gr.addPose(dr);
    for (size_t k = 1; k < truth.size(); ++k) {
      Eigen::Vector3d d = loc::relativePose(truth[k - 1], truth[k]);
      d += Eigen::Vector3d(0.01 * g(rng), 0.01 * g(rng), 0.002 * g(rng));
      dr = loc::composePose(dr, d);
      gr.addPose(dr);
      gr.addOdometry(static_cast<int>(k - 1), static_cast<int>(k), d);
    }
    for (size_t k = 0; k < truth.size(); ++k)
      for (const auto& a : anchors) {
        const double d = (Eigen::Vector3d(truth[k].x(), truth[k].y(), 0.0) - a.position).norm();
        gr.addRange(static_cast<int>(k), a.id, (1.0 + scale) * d + bias + 0.1 * g(rng),
                    Eigen::Vector3d::Zero());
      }
    return gr;
  };
  RangeGraphParams params;
  params.odometry_sigma = {0.01, 0.01, 0.002};
  params.range_sigma = 0.5;
  for (const bool scaled : {true, false}) {
    RangeGraph gr = scaled ? build(0.05, 0.0) : build(0.0, 0.5);
    auto with_biases = params;  // the evidence is read with a bias per anchor free
    with_biases.estimate_bias = true;
    gr.build(with_biases);
    ASSERT_TRUE(gr.solve().usable);
    const auto e = gr.scaleEvidence();
    std::printf(
        "[ GRAPH    ] %s: slope %.4f +- %.4f, explains %.2f of the variance; halves %.4f, "
        "%.4f\n",
        scaled ? "ranges 5 % long" : "every anchor +0.5 m", e.slope[0], e.slope_std[0],
        e.explained[0], e.slope[1], e.slope[2]);
    EXPECT_EQ(loc::scaleStandsOut(e), scaled);
  }
  RangeGraph gr = build(0.05, 0.0);
  params.estimate_scale = true;
  gr.build(params);
  ASSERT_TRUE(gr.solve().usable);
  double se = 0;
  for (size_t k = 0; k < truth.size(); ++k)
    se += (gr.pose(k).head<2>() - truth[k].head<2>()).squaredNorm();
  std::printf("[ GRAPH    ] scale found %+.4f (true +0.05), pose rmse %.4f m\n", gr.scale(),
              std::sqrt(se / truth.size()));
  EXPECT_NEAR(gr.scale(), 0.05, 0.003);
  EXPECT_LT(std::sqrt(se / truth.size()), 0.1);
}

TEST(RangeSlam, ACommonBiasIsOneParameterSharedByEveryAnchor) {
  // Every range 0.7 m long (an antenna delay on the tag): one bias, shared by the five anchors.
  Synthetic s(7, 0.0);
  for (auto& row : s.ranges)
    for (auto& r : row) r += 0.7;
  RangeGraph g = s.graph(s.anchors);
  RangeGraphParams params;
  params.loss = graph::RobustLoss::kNone;
  params.odometry_sigma = {0.02, 0.02, 0.005};
  params.estimate_bias = true;
  params.common_bias = true;
  g.build(params);
  ASSERT_TRUE(g.solve().usable);
  const auto residuals = g.anchorResiduals();
  const auto sigma = g.estimateRangeSigma();
  ASSERT_TRUE(sigma.has_value());
  std::printf("[ GRAPH    ] common bias %.4f m (true 0.7), pose rmse %.4f m, range std %.4f m\n",
              g.bias(0), s.poseRmse(g), *sigma);
  for (size_t i = 0; i < s.anchors.size(); ++i) {
    EXPECT_NEAR(g.bias(i), 0.7, 0.03) << "anchor " << s.anchors[i].id;
    EXPECT_DOUBLE_EQ(residuals[i].bias, g.bias(0));
    EXPECT_NEAR(residuals[i].median, 0.7, 0.05);
  }
  EXPECT_LT(s.poseRmse(g), 0.05);
  // One free parameter, one leverage: the variance component is the simulated 0.1 m.
  EXPECT_NEAR(*sigma, 0.1, 0.01);
  // Back to a bias per anchor: the solve finds 0.7 m on each.
  params.common_bias = false;
  g.build(params);
  ASSERT_TRUE(g.solve().usable);
  for (size_t i = 0; i < s.anchors.size(); ++i) EXPECT_NEAR(g.bias(i), 0.7, 0.05);
}

TEST(RangeSlam, LandmarkObservationsCloseTheLoop) {
  // Odometry only, plus one landmark seen from the first and the last pose of a loop.
  const Synthetic s(11, 0.0);
  RangeGraph g;
  g.setAnchors({});
  for (const auto& p : s.dead_reckoning) g.addPose(p);
  for (size_t k = 0; k + 1 < s.truth.size(); ++k)
    g.addOdometry(static_cast<int>(k), static_cast<int>(k + 1), s.increments[k],
                  Eigen::Vector3d(0.02, 0.02, 0.005));
  const Eigen::Vector2d mark(12.0, 9.0);
  const int l = g.addLandmark(mark + Eigen::Vector2d(0.5, -0.5));
  for (size_t k : {size_t{0}, size_t{1}, s.truth.size() - 2, s.truth.size() - 1}) {
    const Eigen::Vector3d& p = s.truth[k];
    const double c = std::cos(p.z()), sn = std::sin(p.z());
    const Eigen::Vector2d d = mark - p.head<2>();
    g.addLandmarkObservation(static_cast<int>(k), l,
                             {c * d.x() + sn * d.y(), -sn * d.x() + c * d.y()}, 0.02);
  }
  g.build({});
  g.holdPose(0);
  EXPECT_TRUE(g.solve().usable);
  const double end_before = (s.dead_reckoning.back().head<2>() - s.truth.back().head<2>()).norm();
  const double end_after = (g.pose(s.truth.size() - 1).head<2>() - s.truth.back().head<2>()).norm();
  std::printf(
      "[ GRAPH    ] landmark loop closure: end error %.3f m -> %.3f m, landmark error %.3f m\n",
      end_before, end_after, (g.landmark(0) - mark).norm());
  EXPECT_LT(end_after, end_before);
  EXPECT_LT((g.landmark(0) - mark).norm(), 0.1);
}

TEST(RangeSlam, SelfCalibratesAnchors) {
  const Synthetic s(8, 0.0);
  auto start = s.anchors;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g0(0, 0.3);
  for (size_t i = 1; i < start.size(); ++i)
    start[i].position += Eigen::Vector3d(g0(rng), g0(rng), 0.0);
  RangeGraph g = s.graph(start);
  RangeGraphParams params;
  params.loss = graph::RobustLoss::kNone;
  params.estimate_anchors = true;
  params.anchor_prior_sigma = 0.5;
  params.odometry_sigma = {0.02, 0.02, 0.005};
  g.build(params);
  EXPECT_TRUE(g.solve().usable);
  double anchor_err = 0;
  for (size_t i = 0; i < start.size(); ++i)
    anchor_err +=
        (g.anchors()[i].position.head<2>() - s.anchors[i].position.head<2>()).squaredNorm();
  anchor_err = std::sqrt(anchor_err / start.size());
  std::printf(
      "[ GRAPH    ] anchors estimated (start off by 0.3 m): pose rmse %.4f m, anchor rmse %.4f m\n",
      s.poseRmse(g), anchor_err);
  EXPECT_LT(s.poseRmse(g), 0.05);
  EXPECT_LT(anchor_err, 0.05);
}

TEST(RangeSlam, RobustLossAgainstNlosOutliers) {
  const Synthetic s(9, 0.10);  // 10 % of the ranges +1 m
  for (const auto loss :
       {graph::RobustLoss::kNone, graph::RobustLoss::kHuber, graph::RobustLoss::kCauchy}) {
    RangeGraph g = s.graph(s.anchors);
    RangeGraphParams params;
    params.loss = loss;
    params.odometry_sigma = {0.02, 0.02, 0.005};
    g.build(params);
    EXPECT_TRUE(g.solve().usable);
    std::printf("[ GRAPH    ] 10%% NLOS (+1 m), loss %-6s: pose rmse %.4f m\n", loc::enumName(loss),
                s.poseRmse(g));
    if (loss == graph::RobustLoss::kCauchy) {
      EXPECT_LT(s.poseRmse(g), 0.08);
    }
  }
}

// The cross-validation's two settings: a factor f on the odometry edges' std solves as the model
// with every std times f, and an anchor left out solves as the graph without its ranges (5 m
// wrong here), whose residuals are still reported.
TEST(RangeSlam, OdometryFactorAndALeftOutAnchor) {
  const Synthetic s(7, 0.0);
  RangeGraphParams scaled;
  scaled.odometry_sigma = {0.02, 0.02, 0.005};
  scaled.odometry_sigma_factor = 4.0;
  RangeGraphParams wide = scaled;
  wide.odometry_sigma *= 4.0;
  wide.odometry_sigma_factor = 1.0;
  RangeGraph a = s.graph(s.anchors), b = s.graph(s.anchors);
  a.build(scaled);
  b.build(wide);
  ASSERT_TRUE(a.solve().usable);
  ASSERT_TRUE(b.solve().usable);
  for (size_t k = 0; k < a.poses(); ++k) EXPECT_LT((a.pose(k) - b.pose(k)).norm(), 1e-6) << k;

  // The synthetic graph from anchor index `first` on, anchor 0's ranges 5 m long.
  auto graphFrom = [&](size_t first) {
    RangeGraph g;
    g.setAnchors(s.anchors);
    for (const auto& p : s.dead_reckoning) g.addPose(p);
    for (size_t k = 0; k + 1 < s.truth.size(); ++k)
      g.addOdometry(static_cast<int>(k), static_cast<int>(k + 1), s.increments[k]);
    for (size_t k = 0; k < s.truth.size(); ++k)
      for (size_t i = first; i < s.anchors.size(); ++i)
        g.addRange(static_cast<int>(k), s.anchors[i].id, s.ranges[k][i] + (i == 0 ? 5.0 : 0.0),
                   s.tag);
    return g;
  };
  RangeGraph left = graphFrom(0);     // anchor 0's wrong ranges, left out
  RangeGraph without = graphFrom(1);  // the same graph without them
  RangeGraphParams out;
  out.odometry_sigma = {0.02, 0.02, 0.005};
  without.build(out);
  out.left_out_anchor = 0;
  left.build(out);
  ASSERT_TRUE(left.solve().usable);
  ASSERT_TRUE(without.solve().usable);
  for (size_t k = 0; k < left.poses(); ++k)
    EXPECT_LT((left.pose(k) - without.pose(k)).norm(), 1e-6) << k;
  EXPECT_LT(s.poseRmse(left), 0.05);
  const auto residuals = left.rangeResiduals();
  ASSERT_EQ(residuals.size(), s.truth.size() * s.anchors.size());
  std::vector<double> held;
  for (const auto& [id, e] : residuals)
    if (id == s.anchors[0].id) held.push_back(e);
  ASSERT_EQ(held.size(), s.truth.size());
  EXPECT_NEAR(loc::medianOf(held), 5.0, 0.05);
}

TEST(PoseGraph, MrptCircleGraph) {
  const auto g =
      uwbloc::data::readPoseGraph2D("/usr/share/mrpt/datasets/graph_2d_circle_50nodes.graph");
  const auto truth = uwbloc::data::readPoseGraph2D(
      "/usr/share/mrpt/datasets/graph_2d_circle_50nodes_groundtruth.graph");
  ASSERT_EQ(g.vertices.size(), 50u);
  ASSERT_EQ(g.edges.size(), 101u);
  RangeGraph gr;
  for (const auto& [id, pose] : g.vertices) {
    ASSERT_EQ(id, static_cast<int>(gr.poses()));
    gr.addPose(pose);
  }
  for (const auto& e : g.edges) gr.addRelativePose(e.from, e.to, e.delta, e.information);
  RangeGraphParams params;
  gr.build(params);
  gr.holdPose(0);  // gauge: the first pose
  const auto solution = gr.solve();
  EXPECT_TRUE(solution.usable);
  // The same graph started at the ground truth, not iterated: its cost there.
  RangeGraph at_truth;
  for (const auto& [id, pose] : truth.vertices) at_truth.addPose(pose);
  for (const auto& e : g.edges) at_truth.addRelativePose(e.from, e.to, e.delta, e.information);
  RangeGraphParams zero = params;
  zero.max_iterations = 0;
  at_truth.build(zero);
  const double truth_cost = at_truth.solve().initial_cost;
  // Align the first pose with the ground truth's, then compare.
  double sq_before = 0, sq_after = 0, worst = 0;
  for (size_t i = 0; i < gr.poses(); ++i) {
    const Eigen::Vector3d t = truth.vertices.at(static_cast<int>(i));
    const Eigen::Vector3d aligned = uwbloc::loc::composePose(
        truth.vertices.at(0), uwbloc::loc::relativePose(gr.pose(0), gr.pose(i)));
    const Eigen::Vector3d start = uwbloc::loc::composePose(
        truth.vertices.at(0),
        uwbloc::loc::relativePose(g.vertices.at(0), g.vertices.at(static_cast<int>(i))));
    sq_after += (aligned.head<2>() - t.head<2>()).squaredNorm();
    sq_before += (start.head<2>() - t.head<2>()).squaredNorm();
    worst = std::max(worst, (aligned.head<2>() - t.head<2>()).norm());
  }
  const double before = std::sqrt(sq_before / gr.poses()), after = std::sqrt(sq_after / gr.poses());
  std::printf(
      "[ POSEGRPH ] MRPT circle, 50 poses / 101 edges: position RMS error vs ground truth %.4f m "
      "before, %.4f m after (worst %.4f m); cost at the optimum %.4f, at the ground truth %.4f\n",
      before, after, worst, solution.final_cost, truth_cost);
  EXPECT_LT(after, before);
  // The gap to the ground truth is the edges' own noise: the ground truth fits them worse.
  EXPECT_LT(solution.final_cost, truth_cost);
}

// Two tags on one robot that range unlike each other (0.05 m and 0.20 m of noise), the poses
// pinned by their priors: each tag's residual spread is its own noise (within 15 %), where one
// std over both would be neither's.
TEST(RangeGraph, EachTagsSpreadIsItsOwn) {
  const std::vector<uwb::Anchor> anchors = {
      {1, {0, 0, 2}}, {2, {10, 0, 2}}, {3, {10, 10, 2}}, {4, {0, 10, 2}}};
  const std::vector<std::pair<int, Eigen::Vector3d>> tags = {{0, {0.2, 0.1, 1.0}},
                                                             {5, {-0.2, 0.1, 1.0}}};
  const std::map<int, double> sigma = {{0, 0.05}, {5, 0.20}};
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0, 1);
  RangeGraph gr;
  gr.setAnchors(anchors);
  for (int k = 0; k < 400; ++k) {
    const Eigen::Vector3d pose(2.0 + 6.0 * k / 400.0, 3.0 + 2.0 * std::sin(k * 0.05), 0.01 * k);
    const int p = gr.addPose(pose);
    gr.addPosePrior(p, pose, {1e-4, 1e-4, 1e-4});
    for (const auto& [id, lever] : tags)
      for (const auto& a : anchors)
        gr.addRange(p, a.id, uwb::predictRange(pose, lever, a.position) + sigma.at(id) * g(rng),
                    lever, 1.0, id);
  }
  RangeGraphParams params;
  params.loss = RobustLoss::kNone;
  params.range_sigma = 0.1;
  gr.build(params);
  ASSERT_TRUE(gr.solve().usable);
  const auto spread = gr.tagSigmas();
  ASSERT_EQ(spread.size(), 2u);
  for (const auto& [id, s] : spread) {
    std::printf("[ GRAPH    ] tag %d: %ld ranges, robust std %.4f m (true %.2f)\n", id, s.first,
                s.second, sigma.at(id));
    EXPECT_EQ(s.first, 1600);
    EXPECT_NEAR(s.second, sigma.at(id), 0.15 * sigma.at(id)) << id;
  }
}
