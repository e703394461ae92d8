// TW-TOF ranging from raw timestamps: analytic values, counter wrap-around, clock-drift
// behaviour, and agreement with the device's own distance on the Hanyang static recordings.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numeric>

#include "test_helpers.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/uwb/twr.hpp"

using namespace uwbloc;

TEST(Twr, ElapsedTicksHandlesWrapAround) {
  const int64_t wrap40 = int64_t{1} << 40;
  EXPECT_EQ(uwb::elapsedTicks(5, wrap40 - 3), 8);
  EXPECT_EQ(uwb::elapsedTicks(1000, 400), 600);
  // Values exported as wrapped signed 32-bit numbers (a Hanyang row): resp_rx - poll_tx.
  EXPECT_EQ(uwb::elapsedTicks(-1482294179, -1554404436, 32), 72110257);
  EXPECT_EQ(uwb::elapsedTicks(540598834, -1554404436 + 0, 32),
            (int64_t{540598834} + 1554404436) % (int64_t{1} << 32));
}

TEST(Twr, SingleSidedAnalytic) {
  // Eq. (1): d = c (T_round - T_reply - delta) / 2.
  const double tof = 10e-9, reply = 300e-6, delay = 1e-9;
  const double d = uwb::singleSidedTwr(2 * tof + reply + delay, reply, delay);
  EXPECT_NEAR(d, uwb::kSpeedOfLight * tof, 1e-9);
}

TEST(Twr, DoubleSidedCancelsClockDrift) {
  // True time of flight 33.36 ns (10 m); responder clock 20 ppm fast, initiator 5 ppm slow.
  const double tof = 10.0 / uwb::kSpeedOfLight;
  const double ea = -5e-6, eb = 20e-6;
  const double db_true = 400e-6, da_true = 350e-6;
  const double ra = (2 * tof + db_true) * (1 + ea);  // measured by A
  const double db = db_true * (1 + eb);              // measured by B
  const double rb = (2 * tof + da_true) * (1 + eb);  // measured by B
  const double da = da_true * (1 + ea);              // measured by A
  EXPECT_NEAR(uwb::doubleSidedTwr(ra, rb, da, db), 10.0, 1e-3);
  // Single-sided ranging on the same exchange is off by c * db * (eb - ea) / 2, about 1.5 m.
  EXPECT_GT(std::abs(uwb::singleSidedTwr(ra, db) - 10.0), 1.0);
}

// Each static file is one anchor-tag pair at a fixed distance. After fitting one constant
// (antenna delay plus the pair's clock-offset term) the range from raw timestamps must follow
// the device's Distance column closely.
TEST(Twr, ReproducesHanyangDeviceDistance) {
  const std::filesystem::path dir =
      test::sharedData("hanyang_outdoor_uwb/static/LOS/height_100.0cm");
  UWBLOC_REQUIRE_SHARED_DATA(dir);
  std::vector<double> pooled;
  double worst_std = 0.0;
  int files = 0;
  long incomplete = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    const auto f = data::readHanyangStatic(entry.path().string());
    incomplete += f.incomplete_rows;
    std::vector<double> residuals;
    for (const auto& x : f.exchanges) {
      const double round = uwb::elapsedTicks(x.resp_rx, x.poll_tx, 32) * uwb::kDw1000Tick;
      const double reply = uwb::elapsedTicks(x.resp_tx, x.poll_rx, 32) * uwb::kDw1000Tick;
      residuals.push_back(x.device_distance - uwb::singleSidedTwr(round, reply));
    }
    ASSERT_GT(residuals.size(), 50u) << entry.path();
    const double mean = std::accumulate(residuals.begin(), residuals.end(), 0.0) / residuals.size();
    double var = 0.0;
    for (double r : residuals) var += (r - mean) * (r - mean);
    const double sd = std::sqrt(var / (residuals.size() - 1));
    worst_std = std::max(worst_std, sd);
    EXPECT_LT(sd, 0.02) << entry.path() << " fitted constant " << mean;
    pooled.insert(pooled.end(), residuals.begin(), residuals.end());
    ++files;
  }
  const double mean = std::accumulate(pooled.begin(), pooled.end(), 0.0) / pooled.size();
  double var = 0.0;
  for (double r : pooled) var += (r - mean) * (r - mean);
  const double pooled_sd = std::sqrt(var / (pooled.size() - 1));
  std::printf(
      "[ TWR      ] %d files, %zu exchanges, %ld incomplete rows skipped; per-file residual "
      "std <= %.4f m; one constant for all files: %.3f m, residual std %.4f m\n",
      files, pooled.size(), incomplete, worst_std, mean, pooled_sd);
  EXPECT_LT(pooled_sd, 0.06);
}
