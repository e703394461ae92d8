// Each gate rejects what it should on constructed sequences.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "uwbloc/uwb/gates.hpp"

using namespace uwbloc::uwb;

TEST(Validity, RejectsEachBadKind) {
  const ValidityParams p{1e-3, 100.0};
  EXPECT_EQ(checkValidity(std::nan(""), p), RejectReason::kNonFinite);
  EXPECT_EQ(checkValidity(std::numeric_limits<double>::infinity(), p), RejectReason::kNonFinite);
  EXPECT_EQ(checkValidity(0.0, p), RejectReason::kZero);
  EXPECT_EQ(checkValidity(-0.5, p), RejectReason::kNegative);
  EXPECT_EQ(checkValidity(250.0, p), RejectReason::kBeyondMax);
  EXPECT_FALSE(checkValidity(5.0, p).has_value());
  EXPECT_STREQ(toString(RejectReason::kZero), "zero_range");
}

TEST(IncrementQueue, AcceptsSmoothMotionAndRejectsJumps) {
  IncrementQueueGate gate;  // n = 5, zeta = 3, v_max = 2 m/s, floor = 0.3 m
  double t = 0.0, r = 5.0;
  for (int i = 0; i < 20; ++i, t += 0.05, r += 0.04) EXPECT_TRUE(gate.accept(1, t, r)) << i;
  // A 3 m jump in 50 ms is impossible at 2 m/s.
  EXPECT_FALSE(gate.accept(1, t, r + 3.0));
  // The reference stayed on the last good range: the next normal one is accepted.
  t += 0.05;
  r += 0.04;
  EXPECT_TRUE(gate.accept(1, t, r));
  // Anchors are independent.
  EXPECT_TRUE(gate.accept(2, t, 40.0));
}

TEST(IncrementQueue, ReseedsAfterPersistentRejections) {
  IncrementQueueParams p;
  p.max_consecutive_rejects = 4;
  IncrementQueueGate gate(p);
  double t = 0.0;
  for (int i = 0; i < 6; ++i, t += 0.05) EXPECT_TRUE(gate.accept(1, t, 5.0));
  // The anchor really moved (e.g. after a gap the tag is elsewhere): 4 rejections, then re-seed.
  for (int i = 0; i < 4; ++i, t += 0.05) EXPECT_FALSE(gate.accept(1, t, 15.0)) << i;
  EXPECT_EQ(gate.reseeds(), 1);
  EXPECT_TRUE(gate.accept(1, t, 15.02));
}

TEST(IncrementQueue, AllowsLargerStepsAfterAGap) {
  IncrementQueueGate gate;
  EXPECT_TRUE(gate.accept(1, 0.0, 5.0));
  EXPECT_TRUE(gate.accept(1, 0.05, 5.0));
  EXPECT_FALSE(gate.accept(1, 0.10, 7.0));  // 2 m in 50 ms
  EXPECT_TRUE(gate.accept(1, 1.20, 7.0));   // 2 m in 1.15 s at <= 2 m/s
}

TEST(ChiSquare, GatesNormalisedResidual) {
  const ChiSquareGate gate(5.0);
  EXPECT_TRUE(gate.accept(2.0, 1.0));   // 4 <= 5
  EXPECT_FALSE(gate.accept(3.0, 1.0));  // 9 > 5
  EXPECT_TRUE(gate.accept(0.3, 0.02));  // 4.5
  EXPECT_FALSE(gate.accept(1.0, 0.0));  // no variance: cannot judge
  EXPECT_FALSE(gate.accept(NAN, 1.0));
}

TEST(ThreeSigma, RejectsOutliersAgainstTheWindow) {
  ThreeSigmaGate gate;
  // Residuals spread like noise of std 0.1 (a fixed sequence, so every value is in-gate).
  const double spread[] = {0.1, -0.12, 0.05, -0.03, 0.15, -0.1, 0.0, 0.08, -0.14, 0.11};
  for (int i = 0; i < 20; ++i) EXPECT_TRUE(gate.accept(3, spread[i % 10])) << i;
  EXPECT_FALSE(gate.accept(3, 1.0));
  EXPECT_FALSE(gate.accept(3, -0.8));
  EXPECT_TRUE(gate.accept(3, 0.05));
  // A fresh anchor accepts while its window is still filling.
  EXPECT_TRUE(gate.accept(4, 5.0));
}
