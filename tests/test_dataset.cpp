// Dataset layer: manifests, anchors, ground-truth readers, rawlog reading and writing, and the
// errors each bad input gets.
#include <gtest/gtest.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/serialization/CArchive.h>

#include <cmath>
#include <fstream>

#include "test_helpers.hpp"
#include "uwbloc/dataset/dataset.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/ini_file.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/dataset/memory_limits.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/uwb/pose2.hpp"

using namespace uwbloc;
using data::InputError;
using test::expectErrorMentions;
using test::writeText;

namespace {

const std::string kManifest = std::string(UWBLOC_SOURCE_DIR) + "/datasets/mrpt_uwb_demo.ini";

std::string minimalManifest(const std::string& extra_anchor_line = "") {
  return "[dataset]\nrawlog = log.rawlog\n\n[anchors]\nbeacon_001_ID = 1\nbeacon_001_X = 1\n"
         "beacon_001_Y = 2\nbeacon_001_Z = 3\n" +
         extra_anchor_line;
}

}  // namespace

TEST(Manifest, DemoManifestMapsAnchorsIntoTheGroundTruthFrame) {
  const auto m = data::loadManifest(kManifest, "");
  ASSERT_EQ(m.anchors.size(), 3u);
  // Beacon frame minus the start pose (2, 4, 0 deg).
  EXPECT_NEAR(m.anchors[0].position.x(), -1.79, 1e-12);
  EXPECT_NEAR(m.anchors[0].position.y(), -4.55, 1e-12);
  EXPECT_NEAR(m.anchors[2].position.x(), 4.7023, 1e-12);
  EXPECT_NEAR(m.anchors[2].position.y(), 0.3185, 1e-12);
  EXPECT_NEAR(m.anchors[1].position.z(), 1.04, 1e-12);
  EXPECT_EQ(m.ground_truth_format, data::GroundTruthFormat::kStepXyPhi);
  EXPECT_DOUBLE_EQ(*m.tag_height, 1.12);
}

TEST(Manifest, RotatedFrameTransform) {
  const auto dir = test::scratchDir();
  const auto path =
      writeText(dir / "m.ini", minimalManifest("gt_origin_in_anchor_frame = 1 2 90\n"));
  const auto m = data::loadManifest(path, "");
  // p_gt = R(90)^T ((1,2) - (1,2)) = 0.
  EXPECT_NEAR(m.anchors[0].position.head<2>().norm(), 0.0, 1e-12);
  EXPECT_EQ(m.rawlog, (dir / "log.rawlog").string());  // relative to the manifest
}

TEST(Manifest, UnknownKeyNamesFileAndLine) {
  const auto dir = test::scratchDir();
  const auto path = writeText(dir / "m.ini", minimalManifest("beacon_radius = 3\n"));
  expectErrorMentions<InputError>([&] { data::loadManifest(path, ""); },
                                  {path + ":9", "unknown key 'beacon_radius'"});
}

TEST(Manifest, MissingAnchorsAndIncompleteAnchor) {
  const auto dir = test::scratchDir();
  const auto none = writeText(dir / "none.ini", "[dataset]\nrawlog = x.rawlog\n");
  expectErrorMentions<InputError>([&] { data::loadManifest(none, ""); }, {none, "no anchors"});
  const auto partial =
      writeText(dir / "partial.ini", minimalManifest("beacon_002_ID = 2\nbeacon_002_X = 1\n"));
  expectErrorMentions<InputError>([&] { data::loadManifest(partial, ""); },
                                  {partial, "anchor 002 lacks key 'beacon_002_Y'"});
}

TEST(Manifest, MalformedLinesAndValues) {
  const auto dir = test::scratchDir();
  const auto bad_line = writeText(dir / "a.ini", "[dataset]\nrawlog log.rawlog\n");
  expectErrorMentions<InputError>([&] { data::loadManifest(bad_line, ""); },
                                  {bad_line + ":2", "expected 'key = value'"});
  const auto bad_number = writeText(
      dir / "b.ini", minimalManifest("beacon_002_ID = 2\n"
                                     "beacon_002_X = one\nbeacon_002_Y = 0\nbeacon_002_Z = 0\n"));
  expectErrorMentions<InputError>([&] { data::loadManifest(bad_number, ""); },
                                  {bad_number + ":10", "beacon_002_X", "'one'"});
  const auto needs_data = writeText(dir / "c.ini", "[dataset]\nrawlog = ${DATA}/x.rawlog\n");
  expectErrorMentions<InputError>([&] { data::loadManifest(needs_data, ""); },
                                  {needs_data + ":2", "UWBLOC_DATA_DIR"});
}

TEST(Anchors, CsvWithHeaderAndMalformedRow) {
  const auto dir = test::scratchDir();
  const auto good = writeText(dir / "a.csv", "id,x,y,z\n1,0,0,2\n2,6,0,2.1\n");
  const auto anchors = data::loadAnchorsCsv(good);
  ASSERT_EQ(anchors.size(), 2u);
  EXPECT_DOUBLE_EQ(anchors[1].position.z(), 2.1);
  const auto bad = writeText(dir / "b.csv", "id,x,y,z\n1,0,0,2\n2,6,zero,2.1\n");
  expectErrorMentions<InputError>([&] { data::loadAnchorsCsv(bad); },
                                  {bad + ":3", "field 'y'", "'zero'"});
  const auto short_row = writeText(dir / "c.csv", "1,0,0\n");
  expectErrorMentions<InputError>([&] { data::loadAnchorsCsv(short_row); },
                                  {short_row + ":1", "expected 4 fields"});
}

TEST(GroundTruth, ReadersAndErrors) {
  const auto dir = test::scratchDir();
  const auto step = writeText(dir / "s.txt", "0 0 0 0\n1 1.0 2.0 0.5\n");
  const auto s = data::readGroundTruth(step, data::GroundTruthFormat::kStepXyPhi, {10.0, 11.0});
  ASSERT_EQ(s.size(), 2u);
  EXPECT_DOUBLE_EQ(s[1].t, 11.0);
  EXPECT_DOUBLE_EQ(s[1].pose.y(), 2.0);
  expectErrorMentions<InputError>(
      [&] { data::readGroundTruth(step, data::GroundTruthFormat::kStepXyPhi, {10.0}); },
      {step + ":2", "not a step of the rawlog"});
  const auto tum =
      writeText(dir / "t.tum",
                "# t x y z qx qy qz qw\n5.0 1 2 0 0 0 0.7071067811865476 0.7071067811865476\n");
  const auto t = data::readGroundTruth(tum, data::GroundTruthFormat::kTum);
  EXPECT_NEAR(t[0].pose.z(), M_PI / 2, 1e-12);
  const auto back = writeText(dir / "b.txt", "2 0 0 0\n1 0 0 0\n");
  expectErrorMentions<InputError>(
      [&] { data::readGroundTruth(back, data::GroundTruthFormat::kTimeXyPhi); },
      {back + ":2", "time goes backwards"});
  const auto bad = writeText(dir / "c.txt", "2 0 0 0\n3 0 x 0\n");
  expectErrorMentions<InputError>(
      [&] { data::readGroundTruth(bad, data::GroundTruthFormat::kTimeXyPhi); },
      {bad + ":2", "field 'y'"});
}

// A robot turning a full circle in 100 rows, its TUM quaternions written as TUM has them, with
// the scalar first ("qw qx qy qz"), and about y (a y-up frame's heading): the first read
// silently, the second read scalar first and said, the third said.
TEST(GroundTruth, QuaternionsWrittenScalarFirstOrAboutAnotherAxis) {
  const auto dir = test::scratchDir();
  std::string tum, scalar_first, about_y;
  char buf[160];
  for (int k = 0; k < 100; ++k) {
    const double yaw = -M_PI + 2.0 * M_PI * (k + 0.5) / 100.0, c = std::cos(yaw / 2),
                 s = std::sin(yaw / 2);
    std::snprintf(buf, sizeof buf, "%d 1 2 0 0 0 %.12f %.12f\n", k, s, c);
    tum += buf;
    std::snprintf(buf, sizeof buf, "%d 1 2 0 %.12f 0 0 %.12f\n", k, c, s);
    scalar_first += buf;
    std::snprintf(buf, sizeof buf, "%d 1 2 0 0 %.12f 0 %.12f\n", k, s, c);
    about_y += buf;
  }
  const auto read = [&](const std::string& name, const std::string& text,
                        std::vector<std::string>& warnings) {
    return data::readGroundTruth(writeText(dir / name, text), data::GroundTruthFormat::kTum, {},
                                 &warnings);
  };
  std::vector<std::string> said;
  const auto as_tum = read("t.tum", tum, said);
  EXPECT_TRUE(said.empty());
  const auto first = read("w.tum", scalar_first, said);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_NE(said[0].find("w.tum: its quaternions tilt the vertical"), std::string::npos) << said[0];
  EXPECT_NE(said[0].find("they are read scalar first"), std::string::npos) << said[0];
  for (size_t k = 0; k < as_tum.size(); ++k) {
    EXPECT_NEAR(as_tum[k].pose.z(), -M_PI + 2.0 * M_PI * (k + 0.5) / 100.0, 1e-9) << k;
    EXPECT_NEAR(first[k].pose.z(), as_tum[k].pose.z(), 1e-9) << k;
  }
  said.clear();
  read("y.tum", about_y, said);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_NE(said[0].find("y.tum: its quaternions tilt the vertical"), std::string::npos) << said[0];
  EXPECT_NE(said[0].find("cannot be trusted"), std::string::npos) << said[0];
}

// Headings written in degrees ('time x y phi') are read as degrees, loudly: as radians they do not
// follow the travel. A robot driving a 2 m circle and a straight line back, forward then
// backwards, heading 100 deg off the course on the way back (a body frame turned on the robot).
TEST(GroundTruth, HeadingsWrittenInDegrees) {
  const auto dir = test::scratchDir();
  std::string radians, degrees;
  std::vector<double> heading;
  char buf[160];
  for (int k = 0; k < 400; ++k) {
    double x, y, yaw;
    if (k < 200) {
      const double a = 2.0 * M_PI * k / 200.0;
      x = 2.0 * std::cos(a), y = 2.0 * std::sin(a), yaw = a + M_PI / 2;
    } else {
      x = 2.0 - 0.05 * (k - 200), y = 0.0, yaw = (k < 300 ? 0.0 : M_PI) + 100.0 * M_PI / 180.0;
    }
    heading.push_back(wrapAngle(yaw));
    std::snprintf(buf, sizeof buf, "%.1f %.6f %.6f %.9f\n", 0.1 * k, x, y, yaw);
    radians += buf;
    std::snprintf(buf, sizeof buf, "%.1f %.6f %.6f %.9f\n", 0.1 * k, x, y, yaw * 180.0 / M_PI);
    degrees += buf;
  }
  std::vector<std::string> said;
  const auto as_radians = data::readGroundTruth(writeText(dir / "r.txt", radians),
                                                data::GroundTruthFormat::kTimeXyPhi, {}, &said);
  EXPECT_TRUE(said.empty()) << said.front();
  const auto as_degrees = data::readGroundTruth(writeText(dir / "d.txt", degrees),
                                                data::GroundTruthFormat::kTimeXyPhi, {}, &said);
  ASSERT_EQ(said.size(), 1u);
  EXPECT_NE(said[0].find("d.txt: its headings are read as degrees"), std::string::npos) << said[0];
  for (size_t k = 0; k < heading.size(); ++k) {
    EXPECT_NEAR(wrapAngle(as_radians[k].pose.z() - heading[k]), 0.0, 1e-9) << k;
    EXPECT_NEAR(wrapAngle(as_degrees[k].pose.z() - heading[k]), 0.0, 1e-9) << k;
  }
}

TEST(Rawlog, DemoStreamMatchesTheKnownLayout) {
  const auto rec = data::readRawlog(test::kDemoRawlog);
  EXPECT_EQ(rec.step_times.size(), 342u);  // one per action + sensory-frame pair
  EXPECT_EQ(rec.counts.at("beacon_observations"), 339);
  EXPECT_EQ(rec.counts.at("scans"), 343);
  EXPECT_EQ(rec.counts.at("timestamp_from_frame"), 339);  // the beacon observations carry 0
  long ranges = 0, odometry = 0;
  double last = -1e300;
  for (const auto& e : rec.events) {
    ASSERT_GE(loc::eventTime(e), last);
    last = loc::eventTime(e);
    if (const auto* r = std::get_if<uwb::Range>(&e)) {
      ++ranges;
      EXPECT_NEAR(r->tag_on_robot.z(), 1.12, 1e-6);
      EXPECT_NEAR(r->tag_on_robot.x(), 0.16, 1e-6);
    }
    odometry += std::holds_alternative<loc::OdometryIncrement>(e);
  }
  EXPECT_EQ(ranges, 3 * 339);
  EXPECT_EQ(odometry, 343);
}

TEST(Rawlog, WriteThenReadRoundTrip) {
  const auto dir = test::scratchDir();
  std::vector<loc::Event> events;
  for (int k = 0; k < 20; ++k) {
    const double t = 1.7e9 + 0.1 * k;
    for (int a = 1; a <= 3; ++a) {
      uwb::Range r;
      r.t = t;
      r.anchor_id = a;
      r.range = 2.0 + 0.25 * a + 0.01 * k;
      r.tag_on_robot << 0.1, -0.05, 1.2;
      events.emplace_back(r);
    }
    loc::OdometryIncrement o;
    o.t = t + 0.05;
    o.delta << 0.1, 0.0, 0.02;
    events.emplace_back(o);
  }
  const auto path = (dir / "rt.rawlog").string();
  data::writeRawlog(path, events);
  const auto rec = data::readRawlog(path);
  std::vector<uwb::Range> in, out;
  for (const auto& e : events)
    if (auto* r = std::get_if<uwb::Range>(&e)) in.push_back(*r);
  long odometry = 0;
  for (const auto& e : rec.events) {
    if (auto* r = std::get_if<uwb::Range>(&e)) out.push_back(*r);
    if (auto* o = std::get_if<loc::OdometryIncrement>(&e)) {
      ++odometry;
      EXPECT_NEAR(o->delta.x(), 0.1, 1e-9);
      EXPECT_NEAR(o->delta.z(), 0.02, 1e-9);
    }
  }
  EXPECT_EQ(odometry, 20);  // an origin reading is written first, so no increment is lost
  ASSERT_EQ(in.size(), out.size());
  for (size_t i = 0; i < in.size(); ++i) {
    EXPECT_NEAR(in[i].t, out[i].t, 1e-6);
    EXPECT_EQ(in[i].anchor_id, out[i].anchor_id);
    EXPECT_NEAR(in[i].range, out[i].range, 1e-5);  // stored as float
    EXPECT_NEAR((in[i].tag_on_robot - out[i].tag_on_robot).norm(), 0.0, 1e-6);
  }
}

TEST(Rawlog, MissingTruncatedAndCorruptFilesNameTheFile) {
  const auto dir = test::scratchDir();
  const auto missing = (dir / "missing.rawlog").string();
  expectErrorMentions<InputError>([&] { data::readRawlog(missing); }, {missing, "not found"});

  // A truncated copy of the demo (gzip stream cut in the middle).
  std::ifstream src(test::kDemoRawlog, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
  const auto truncated = (dir / "truncated.rawlog").string();
  std::ofstream(truncated, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  expectErrorMentions<InputError>([&] { data::readRawlog(truncated); }, {truncated, "rawlog"});

  // Garbage bytes inside the stream.
  std::string corrupted = bytes;
  for (size_t i = corrupted.size() / 3; i < corrupted.size() / 3 + 64; ++i) corrupted[i] ^= 0x5a;
  const auto corrupt = (dir / "corrupt.rawlog").string();
  std::ofstream(corrupt, std::ios::binary) << corrupted;
  expectErrorMentions<InputError>([&] { data::readRawlog(corrupt); }, {corrupt, "rawlog"});

  const auto text = writeText(dir / "text.rawlog", "this is not a rawlog\n");
  expectErrorMentions<InputError>([&] { data::readRawlog(text); }, {text, "rawlog"});

  // An uncompressed copy with one object's class name spoilt: one line naming the object and
  // the byte where it starts, and nothing of MRPT's nested exception text.
  const auto plain = data::readRawlog(test::kDemoRawlog);  // (the demo reads cleanly)
  mrpt::io::CFileGZInputStream gz(test::kDemoRawlog);
  std::string raw;
  char buf[65536];
  for (size_t n; (n = gz.Read(buf, sizeof buf)) > 0;) raw.append(buf, n);
  const auto at = raw.find("CActionCollection", raw.size() / 2);
  ASSERT_NE(at, std::string::npos);
  raw[at] = 'X';
  const auto spoilt = (dir / "spoilt.rawlog").string();
  std::ofstream(spoilt, std::ios::binary) << raw;
  try {
    data::readRawlog(spoilt);
    FAIL() << "a spoilt class name was read";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("object "), std::string::npos) << what;
    EXPECT_NE(what.find("at byte "), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    EXPECT_EQ(what.find("===="), std::string::npos) << what;
  }
  const auto empty = writeText(dir / "empty.rawlog", "");
  expectErrorMentions<InputError>([&] { data::readRawlog(empty); }, {empty, "rawlog"});
}

TEST(Rawlog, ACorruptCountIsRefusedBeforeItIsAllocated) {
  // The demo's uncompressed stream with the first beacon observation's measurement count set to
  // 2^24: MRPT would resize to 16 M measurements (about 1 GB) before finding that the stream
  // ends. The reader caps every allocation by what is left of the stream.
  ASSERT_TRUE(data::allocationGuardActive());
  const auto dir = test::scratchDir();
  mrpt::io::CFileGZInputStream gz(test::kDemoRawlog);
  std::string raw;
  char buf[65536];
  for (size_t n; (n = gz.Read(buf, sizeof buf)) > 0;) raw.append(buf, n);
  const std::string name = "CObservationBeaconRanges";
  const auto at = raw.find(name);
  ASSERT_NE(at, std::string::npos);
  // Version byte, then min, max and std (three floats), then the uint32 count.
  const size_t count_at = at + name.size() + 1 + 12;
  ASSERT_EQ(raw[at + name.size()], 3) << "serialisation version";
  raw.replace(count_at, 4, std::string("\x00\x00\x00\x01", 4));
  const auto path = (dir / "count.rawlog").string();
  std::ofstream(path, std::ios::binary) << raw;
  expectErrorMentions<InputError>([&] { data::readRawlog(path); },
                                  {path, "object ", "at byte ", "claims", "corrupt count"});
}

TEST(Rawlog, AStreamThatCrashesMrptsDeserialiserIsAnErrorNotACrash) {
  // Found by fuzzing: a CActionRobotMovement2D whose estimation method is not odometry and whose
  // pose PDF is a CPose2D; MRPT reads it into a CPosePDF pointer, gets null and dereferences it.
  // The deserialiser runs in a child process: the caller gets an error naming the object.
  const std::string path = std::string(UWBLOC_SOURCE_DIR) +
                           "/tests/fuzz/corpus/fuzz_rawlog/crash_wrong_class_posepdf.rawlog";
  expectErrorMentions<InputError>(
      [&] { data::readRawlog(path); },
      {path, "deserialiser crashed", "signal 11", "object 2", "at byte "});
}

TEST(Rawlog, AnImuReadingWithoutThePlanarFieldsIsCountedNotThrown) {
  // MRPT's CObservationIMU::get throws for a field that is not present: a reading with the yaw
  // rate only is rejected and counted; the reading with all three is kept.
  const auto path = (test::scratchDir() / "imu.rawlog").string();
  {
    mrpt::io::CFileGZOutputStream out(path);
    auto archive = mrpt::serialization::archiveFrom(out);
    mrpt::obs::CObservationIMU partial;
    partial.timestamp = mrpt::Clock::fromDouble(1.7e9);
    partial.set(mrpt::obs::IMU_YAW_VEL, 0.1);
    archive << partial;
    mrpt::obs::CObservationIMU full = partial;
    full.timestamp = mrpt::Clock::fromDouble(1.7e9 + 0.01);
    full.set(mrpt::obs::IMU_X_ACC, 0.2);
    full.set(mrpt::obs::IMU_Y_ACC, 0.3);
    archive << full;
  }
  const auto rec = data::readRawlog(path);
  EXPECT_EQ(rec.counts.at("rejected_imu_without_planar_fields"), 1);
  EXPECT_EQ(rec.counts.at("imu_observations"), 1);
}

TEST(MemoryLimits, ByteSizesParseAndTheCapRefusesLargerAllocations) {
  EXPECT_EQ(data::parseByteSize("512M"), std::size_t{512} << 20);
  EXPECT_EQ(data::parseByteSize("4G"), std::size_t{4} << 30);
  EXPECT_EQ(data::parseByteSize("1.5GiB"), static_cast<std::size_t>(1.5 * (1 << 30)));
  EXPECT_EQ(data::parseByteSize("2000"), 2000u);
  EXPECT_FALSE(data::parseByteSize("lots"));
  EXPECT_FALSE(data::parseByteSize("-1G"));
  EXPECT_FALSE(data::parseByteSize("3X"));
  EXPECT_EQ(data::formatBytes(1536.0 * (1 << 20)), "1.5 GiB");
  {
    const data::ScopedAllocationCap cap(1 << 20);
    EXPECT_THROW(std::vector<char>(2 << 20), data::AllocationOverCap);
    EXPECT_NO_THROW(std::vector<char>(1 << 19));
  }
  EXPECT_NO_THROW(std::vector<char>(2 << 20));  // the cap ends with its scope
}

TEST(Dataset, DemoLoadsWithGroundTruthOnStepTimes) {
  const auto ds = data::loadDataset(kManifest, "");
  EXPECT_EQ(ds.ground_truth.size(), 342u);
  EXPECT_NEAR(ds.duration(), 363.0, 1.0);
  EXPECT_EQ(ds.anchors.size(), 3u);
  // The GT starts at the origin at the time of the first step.
  EXPECT_NEAR(ds.ground_truth.front().pose.norm(), 0.0, 1e-9);
}

TEST(Dataset, RangeFeatureSideFileErrors) {
  const auto dir = test::scratchDir();
  std::vector<loc::Event> events;
  uwb::Range r;
  r.t = 12.5;
  r.anchor_id = 3;
  r.range = 4.0;
  events.emplace_back(r);
  const auto good = writeText(dir / "f.csv",
                              "t,anchor_id,range,rx_power_dbm,fp_power_dbm\n"
                              "12.500000,3,4.0,-80.1,-82.5\n");
  EXPECT_EQ(data::attachRangeFeatures(good, events), 1);
  EXPECT_DOUBLE_EQ(*std::get<uwb::Range>(events[0]).fp_power_dbm, -82.5);
  const auto bad = writeText(dir / "g.csv",
                             "t,anchor_id,range,rx_power_dbm,fp_power_dbm\n"
                             "12.5,3,4.0,-80.1\n");
  expectErrorMentions<InputError>([&] { data::attachRangeFeatures(bad, events); },
                                  {bad + ":2", "expected 5 fields"});
  const auto no_power = writeText(dir / "h.csv", "t,anchor_id,range,rx_power_dbm\n");
  expectErrorMentions<InputError>([&] { data::attachRangeFeatures(no_power, events); },
                                  {no_power + ":1", "no 'fp_power_dbm' column"});
}

// Two tags ranging to one anchor at the same instant: each range takes its own tag's row (the
// file written by formatRangeFeatures, read back), and a file without tag_id fits any tag.
TEST(Dataset, RangeFeaturesKeepEachTagApart) {
  const auto dir = test::scratchDir();
  std::vector<loc::Event> events;
  for (int tag : {0, 1}) {
    uwb::Range r;
    r.t = 7.25;
    r.anchor_id = 2;
    r.tag_id = tag;
    r.range = 3.0 + tag;
    r.rx_power_dbm = -80.0 - tag;
    r.fp_power_dbm = -85.0 - 5 * tag;
    events.emplace_back(r);
  }
  const std::string text = data::formatRangeFeatures(events);
  EXPECT_NE(text.find(",tag_id\n"), std::string::npos) << text;
  auto read = events;
  for (auto& e : read) std::get<uwb::Range>(e).fp_power_dbm.reset();
  EXPECT_EQ(data::attachRangeFeatures(writeText(dir / "both.csv", text), read), 2);
  EXPECT_DOUBLE_EQ(*std::get<uwb::Range>(read[0]).fp_power_dbm, -85.0);
  EXPECT_DOUBLE_EQ(*std::get<uwb::Range>(read[1]).fp_power_dbm, -90.0);
  const auto untagged = writeText(dir / "old.csv",
                                  "t,anchor_id,range,rx_power_dbm,fp_power_dbm\n"
                                  "7.250000,2,3.0,-80.0,-85.0\n");
  for (auto& e : read) std::get<uwb::Range>(e).fp_power_dbm.reset();
  EXPECT_EQ(data::attachRangeFeatures(untagged, read), 2);
  EXPECT_DOUBLE_EQ(*std::get<uwb::Range>(read[1]).fp_power_dbm, -85.0);
}

TEST(Ini, CommentsStartOnlyAtTheLineStartOrAfterWhiteSpace) {
  // MRPT's INI files use '#', ';' and '//' comments; inside a value they are characters.
  const auto ini = data::IniFile::fromString(
      "# a comment\n"
      "; another\n"
      "// and another\n"
      "[pf-ibas+graph]\n"
      "front = pf-ibas:n=60;ibas_step=0.2   # the front end's own parameters\n"
      "map = /data//maps/office.yaml ; a path with a double slash\n"
      "label = room#3\n"
      "note = a value\t// tab before the comment\n",
      "test.ini");
  EXPECT_EQ(*ini.get("pf-ibas+graph", "front"), "pf-ibas:n=60;ibas_step=0.2");
  EXPECT_EQ(*ini.get("pf-ibas+graph", "map"), "/data//maps/office.yaml");
  EXPECT_EQ(*ini.get("pf-ibas+graph", "label"), "room#3");
  EXPECT_EQ(*ini.get("pf-ibas+graph", "note"), "a value");
}
