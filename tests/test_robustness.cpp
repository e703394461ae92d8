// Bad and unusual inputs from the robustness review, each turned into a clean, named error (or
// a bounded result): special files, absurd values, long and control-character tokens, a TUM file
// read as 'time x y phi', NaN anchors, scenario sizes that would not fit in memory, a segment
// walk with far-away ends.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <limits>

#include "test_helpers.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/ini_file.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/dataset/scenario.hpp"
#include "uwbloc/dataset/world.hpp"
#include "uwbloc/localization/params.hpp"

using namespace uwbloc;
using test::expectErrorMentions;
using test::writeText;

TEST(Robustness, SpecialFilesAreRefusedNotRead) {
  const auto dir = test::scratchDir();
  const auto fifo = (dir / "manifest.fifo").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  // Reading a FIFO would block for ever: every reader refuses it first.
  expectErrorMentions<data::InputError>([&] { data::IniFile::load(fifo); },
                                        {fifo, "not a regular file"});
  expectErrorMentions<data::InputError>([&] { data::loadAnchorsCsv(fifo); },
                                        {fifo, "not a regular file"});
  expectErrorMentions<data::InputError>([&] { data::IniFile::load(dir.string()); },
                                        {"not a regular file"});
}

TEST(Robustness, TokensInMessagesAreShortAndPrintable) {
  const std::string quoted = loc::quoteToken(std::string(5000, 'x') + "\x1b[31m");
  EXPECT_LE(quoted.size(), 90u);
  EXPECT_EQ(quoted.find('\x1b'), std::string::npos);
  EXPECT_EQ(loc::quoteToken("a\x1b"
                            "b"),
            "'a\\x1bb'");
  loc::ParamSet set = loc::ParamSet::parse("q=" + std::string(100000, '9') + "z", "method 'm'");
  double q = 0;
  try {
    set.read("q", q);
    ADD_FAILURE() << "accepted";
  } catch (const loc::ParamError& e) {
    EXPECT_LT(std::string(e.what()).size(), 200u);
  }
}

TEST(Robustness, NonFiniteAndNonIntegerValuesInManifestsAreErrors) {
  const auto dir = test::scratchDir();
  writeText(dir / "a.csv", "id,x,y,z\nnan,0,0,2\n");
  expectErrorMentions<data::InputError>([&] { data::loadAnchorsCsv((dir / "a.csv").string()); },
                                        {"a.csv:2", "integer"});
  writeText(dir / "b.csv", "id,x,y,z\n1,nan,0,2\n");
  expectErrorMentions<data::InputError>([&] { data::loadAnchorsCsv((dir / "b.csv").string()); },
                                        {"b.csv:2", "finite"});
  const auto ini = writeText(dir / "m.ini",
                             "[dataset]\nrawlog = x.rawlog\n[anchors]\nbeacon_001_ID = 1\n"
                             "beacon_001_X = nan\nbeacon_001_Y = 0\nbeacon_001_Z = 1\n");
  expectErrorMentions<data::InputError>([&] { data::loadManifest(ini, ""); },
                                        {"m.ini:5", "finite"});
}

TEST(Robustness, ATumFileReadAsTimeXyPhiIsNamed) {
  const auto dir = test::scratchDir();
  const auto tum = writeText(dir / "gt.tum", "1.0 2 3 0 0 0 0.1 0.995\n");
  expectErrorMentions<data::InputError>(
      [&] { data::readGroundTruth(tum, data::GroundTruthFormat::kTimeXyPhi); },
      {"gt.tum:1", "8 fields", "tum"});
}

TEST(Robustness, ScenarioSizesThatWouldNotFitAreErrors) {
  const auto dir = test::scratchDir();
  const std::string base =
      "[scenario]\nduration = 10\n[anchors]\nanchor_1 = 0 0 2\n"
      "anchor_2 = 5 0 2\nanchor_3 = 0 5 2\n[trajectory]\n"
      "waypoints = 1 1, 2 2\nspeed = 0.5\n";
  const auto fine = writeText(dir / "ok.ini", base + "[world]\nbounds = 0 0 6 6\n");
  EXPECT_NO_THROW(data::loadScenario(fine));
  const auto tiny =
      writeText(dir / "r.ini", base + "[world]\nbounds = 0 0 6 6\nresolution = 1e-5\n");
  expectErrorMentions<data::InputError>([&] { data::loadScenario(tiny); }, {"r.ini", "resolution"});
  const auto huge = writeText(dir / "b.ini", base + "[world]\nbounds = 0 0 1e7 1e7\n");
  expectErrorMentions<data::InputError>([&] { data::loadScenario(huge); }, {"b.ini", "bounds"});
  const auto rays = writeText(dir / "l.ini", base +
                                                 "[world]\nbounds = 0 0 6 6\n[lidar]\n"
                                                 "preset = sick_lms\nrays = 1e9\n");
  expectErrorMentions<data::InputError>([&] { data::loadScenario(rays); }, {"l.ini", "rays"});
}

TEST(Robustness, SegmentWalkIsBoundedByTheMap) {
  // A segment from inside the map to a point 1e12 m away: only the part inside is walked.
  const auto map = data::mapFromRectangles({0, 0, 10, 10}, {{6, 4, 7, 6}}, 0.05, false);
  EXPECT_TRUE(map.segmentBlocked({2, 5}, {1e12, 5}));
  EXPECT_FALSE(map.segmentBlocked({2, 1}, {1e12, 1}));
  EXPECT_FALSE(map.segmentBlocked({2, 1}, {std::numeric_limits<double>::infinity(), 1}));
  EXPECT_FALSE(map.segmentBlocked({-1e12, -1e12}, {-1e12 + 1, -1e12}));
}
