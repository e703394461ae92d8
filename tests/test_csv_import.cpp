// Plain-CSV recordings in and out: a simulated recording exported and imported again scores
// identically; the odometry kinds; headers; a reference without heading; asymmetric scans;
// malformed rows named by file and line.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "csv_drive.hpp"
#include "simulated_scenario.hpp"
#include "test_helpers.hpp"
#include "uwbloc/dataset/csv_import.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/librsf_import.hpp"
#include "uwbloc/dataset/odometry_check.hpp"
#include "uwbloc/dataset/range_geometry.hpp"
#include "uwbloc/evaluation/metrics.hpp"
#include "uwbloc/evaluation/runner.hpp"
#include "uwbloc/uwb/range_model.hpp"

using namespace uwbloc;

namespace {

// Splits the exporter's argument line back into a request.
data::CsvImportRequest requestFrom(const std::string& args) {
  data::CsvImportRequest r;
  std::istringstream in(args);
  std::string key, value;
  while (in >> key >> value) {
    auto numbers = [&] {
      std::vector<double> v;
      std::istringstream s(value);
      for (std::string p; std::getline(s, p, ',');) v.push_back(std::stod(p));
      return v;
    };
    if (key == "--ranges")
      r.ranges = value;
    else if (key == "--anchors")
      r.anchors = value;
    else if (key == "--odometry")
      r.odometry = value;
    else if (key == "--imu")
      r.imu = value;
    else if (key == "--reference")
      r.reference = value;
    else if (key == "--scans")
      r.scans = value;
    else if (key == "--map")
      r.map = value;
    else if (key == "--scan-max-range")
      r.scan_max_range = std::stod(value);
    else if (key == "--scan-pose") {
      const auto v = numbers();
      r.scan_pose = Eigen::Vector3d(v[0], v[1], v[2]);
      r.scan_height = v[3];
    } else if (key == "--tag") {
      const auto v = numbers();
      r.tags[static_cast<int>(v[0])] = Eigen::Vector3d(v[1], v[2], v[3]);
    } else {
      ADD_FAILURE() << "unknown argument " << key;
    }
  }
  return r;
}

// Three anchors 8 m apart as an anchors CSV, and a tag driving 1 m along x among them at 1 m
// height: 100 epochs 0.1 s apart from t0, each a range to every anchor. Calls range(t, anchor,
// distance) for each range and pose(t, x, y) for each epoch.
constexpr const char* kThreeAnchors = "1,0,0,1\n2,8,0,1\n3,0,8,1\n";
template <class Range, class Pose>
void driveAmongThreeAnchors(double t0, Range&& range, Pose&& pose) {
  const Eigen::Vector3d anchors[] = {{0, 0, 1}, {8, 0, 1}, {0, 8, 1}};
  for (int k = 0; k < 100; ++k) {
    const double t = t0 + 0.1 * k;
    const Eigen::Vector3d p(2.0 + 0.01 * k, 3.0, 1.0);
    for (int a = 1; a <= 3; ++a) range(t, a, (anchors[a - 1] - p).norm());
    pose(t, p.x(), p.y());
  }
}

// A drive's `ranges` and `ref` (CSV text) imported into dir/out among the four anchors, the tag
// at `tag` (or only at its height when `height_only`): the manifest.
std::string importDrive(const std::filesystem::path& dir, const std::string& ranges,
                        const std::string& ref, const Eigen::Vector3d& tag, bool height_only) {
  data::CsvImportRequest r;
  r.ranges = test::writeText(dir / "r.csv", ranges);
  r.anchors = test::writeText(dir / "a.csv", test::kFourAnchors);
  r.reference = test::writeText(dir / "ref.csv", ref);
  if (height_only)
    r.tag_height = tag.z();
  else
    r.tags[0] = tag;
  return data::importCsv(r, (dir / "out").string()).manifest;
}

// The warning that loading `manifest` gives about `what`, or "".
std::string warningAbout(const std::string& manifest, const std::string& what) {
  for (const auto& w : data::loadDataset(manifest, "").warnings)
    if (w.find(what) != std::string::npos) return w;
  return std::string();
}

}  // namespace

TEST(CsvImport, ARoundTripScoresIdentically) {
  const auto dir = test::scratchDir();
  const data::Dataset sim = test::simulatedScenario("pfibas_room", 2);
  const std::string args = data::exportCsv(sim, (dir / "csv").string());
  const auto s = data::importCsv(requestFrom(args), (dir / "imported").string());
  const data::Dataset back = data::loadDataset(s.manifest, "");
  ASSERT_EQ(back.events.size(), sim.events.size());
  ASSERT_EQ(back.ground_truth.size(), sim.ground_truth.size());
  // Each sensor: UWB (uwb-ekf), odometry (odom), IMU (uwb-ins), LiDAR and map (fused-pf).
  for (const char* m : {"uwb-ekf", "odom", "uwb-ins", "fused-pf"}) {
    const auto a = eval::evaluateMethod(sim, m, 1, 1);
    const auto b = eval::evaluateMethod(back, m, 1, 1);
    std::printf("[ CSV      ] %-9s rmse_2d %.6f m simulated, %.6f m after the round trip\n", m,
                a.metrics.rmse_2d, b.metrics.rmse_2d);
    EXPECT_EQ(a.metrics.steps, b.metrics.steps) << m;
    EXPECT_NEAR(a.metrics.rmse_2d, b.metrics.rmse_2d, 1e-9) << m;
    EXPECT_NEAR(a.metrics.max_2d, b.metrics.max_2d, 1e-9) << m;
  }
}

TEST(CsvImport, ReadsEveryOdometryKind) {
  const auto dir = test::scratchDir();
  test::writeText(dir / "a.csv", "1,0,0,1\n2,10,0,1\n3,0,10,1\n");
  test::writeText(dir / "r.csv", "t,anchor,range\n10,1,5\n10.1,2,5\n");
  // A robot driving a circle of radius 2 m at 0.5 m/s, sampled at 10 Hz, as the three kinds.
  std::string poses = "t,x,y,theta\n", vel = "t,v,omega\n", inc = "t,dx,dy,dtheta\n", ref = "",
              plain_poses;
  const double v = 0.5, w = 0.25;
  Eigen::Vector3d prev(0, 0, 0);
  for (int k = 0; k <= 200; ++k) {
    const double t = 10.0 + 0.1 * k, a = w * 0.1 * k;
    const Eigen::Vector3d p(2.0 * std::sin(a), 2.0 * (1 - std::cos(a)), a);
    char buf[200];
    std::snprintf(buf, sizeof buf, "%.3f,%.12f,%.12f,%.12f\n", t, p.x(), p.y(), p.z());
    poses += buf;
    plain_poses += buf;
    ref += buf;
    std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f\n", t, v, w);
    vel += buf;
    const Eigen::Vector3d d = relativePose(prev, p);
    if (k > 0) {
      std::snprintf(buf, sizeof buf, "%.3f,%.12f,%.12f,%.12f\n", t, d.x(), d.y(), d.z());
      inc += buf;
    }
    prev = p;
  }
  test::writeText(dir / "ref.csv", ref);
  auto finalPose = [&](const std::string& file, const std::string& kind, bool with_ref) {
    data::CsvImportRequest r;
    r.ranges = (dir / "r.csv").string();
    r.anchors = (dir / "a.csv").string();
    r.odometry = (dir / file).string();
    r.odometry_kind = kind;
    if (with_ref) r.reference = (dir / "ref.csv").string();
    const auto s = data::importCsv(r, (dir / ("out_" + file + kind)).string());
    const auto ds = data::loadDataset(s.manifest, "");
    Eigen::Vector3d pose = Eigen::Vector3d::Zero();
    for (const auto& e : ds.events)
      if (const auto* o = std::get_if<loc::OdometryIncrement>(&e))
        pose = composePose(pose, o->delta);
    return std::pair(pose, s);
  };
  const Eigen::Vector3d end(2.0 * std::sin(5.0), 2.0 * (1 - std::cos(5.0)), wrapAngle(5.0));
  for (const auto& [file, text] :
       {std::pair{"poses.csv", poses}, std::pair{"vel.csv", vel}, std::pair{"inc.csv", inc}}) {
    test::writeText(dir / file, text);
    const auto [pose, s] = finalPose(file, "auto", false);
    EXPECT_LT((pose.head<2>() - end.head<2>()).norm(), 1e-5) << file;
    EXPECT_NEAR(wrapAngle(pose.z() - end.z()), 0.0, 1e-6) << file;
  }
  // No header: four columns need a kind, or a reference to decide by.
  test::writeText(dir / "plain.csv", plain_poses);
  test::expectErrorMentions<data::InputError>([&] { finalPose("plain.csv", "auto", false); },
                                              {"plain.csv", "--odometry-kind"});
  const auto [pose, s] = finalPose("plain.csv", "auto", true);
  EXPECT_LT((pose.head<2>() - end.head<2>()).norm(), 1e-5);
  bool noted = false;
  for (const auto& n : s.notes) noted |= n.find("Odometry read as poses") != std::string::npos;
  EXPECT_TRUE(noted);
}

TEST(CsvImport, AReferenceWithoutHeadingIsNotScoredForHeading) {
  const auto dir = test::scratchDir();
  test::writeText(dir / "a.csv", kThreeAnchors);
  std::string ranges = "t,anchor_id,range,tag_id,rx_power,fp_power\n", ref;
  char buf[160];
  driveAmongThreeAnchors(
      5.0,
      [&](double t, int a, double r) {
        std::snprintf(buf, sizeof buf, "%.2f,%d,%.6f,0,-80,-82\n", t, a, r);
        ranges += buf;
      },
      [&](double t, double x, double y) {
        std::snprintf(buf, sizeof buf, "%.2f %.4f %.4f\n", t, x, y);
        ref += buf;
      });
  data::CsvImportRequest r;
  r.ranges = test::writeText(dir / "r.csv", ranges);
  r.anchors = (dir / "a.csv").string();
  r.reference = test::writeText(dir / "ref.txt", ref);
  r.tag_height = 1.0;
  const auto s = data::importCsv(r, (dir / "out").string());
  const auto ds = data::loadDataset(s.manifest, "");
  EXPECT_FALSE(ds.manifest.reference_heading);
  EXPECT_EQ(ds.counts.at("ranges_with_features"), 300);  // the powers reach the ranges
  const auto m = eval::evaluateMethod(ds, "uwb-gn", 1, 1);
  EXPECT_LT(m.metrics.rmse_2d, 1e-3);
  EXPECT_TRUE(std::isnan(m.metrics.rmse_yaw_deg));
}

// Units a device log often carries: stamps in milliseconds, microseconds or nanoseconds since the
// epoch (after the year 3000 read as seconds) and ranges in millimetres or centimetres (a median
// range over 10 times the anchors' 8 m spacing and over 100 m). Each file is read in the unit
// that makes sense of it, loudly, and the recording scores as the one in seconds and metres.
// Asked for seconds, the milliseconds are refused, every row, and the import fails naming the
// file; ranges no unit puts among the anchors are an error; stamps in milliseconds from zero
// (epochs a second apart read as 1000 s) are warned about.
// Anchors and tags named as devices write them ("1C8D", "6E44", which reads as a number but
// holds a letter; "left"): numbered around the integer ids that the files use (here anchors 2 and
// 4, and 1 in the ranges alone, an anchor the file lacks), listed in ids.csv, and scored as the
// same drive with numbered ids is. A number that is no integer is an error, not a name.
TEST(CsvImport, NamedAnchorsAndTags) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d tag(0.0, 0.0, 0.8);
  const auto [ranges, ref] = test::driveACircle(tag, Eigen::Vector3d::Zero());
  const std::map<std::string, std::string> names = {{"1", "1C8D"}, {"3", "6E44"}};
  std::string named = "t,anchor_id,range,tag_id\n", numbered = "t,anchor_id,range,tag_id\n";
  int row = 0;
  for (size_t a = ranges.find('\n') + 1, b; (b = ranges.find('\n', a)) != std::string::npos;
       a = b + 1, ++row) {
    const std::string line = ranges.substr(a, b - a);
    const size_t c1 = line.find(','), c2 = line.find(',', c1 + 1);
    const std::string id = line.substr(c1 + 1, c2 - c1 - 1);
    const auto it = names.find(id);
    named += line.substr(0, c1 + 1) + (it == names.end() ? id : it->second) + line.substr(c2) +
             ",left\n";
    numbered += line + ",0\n";
    if (row % 50 == 0) {  // a range to anchor 1, which the anchors file lacks
      named += line.substr(0, c1) + ",1,3.0,left\n";
      numbered += line.substr(0, c1) + ",9,3.0,0\n";
    }
  }
  data::CsvImportRequest r;
  r.reference = test::writeText(dir / "ref.csv", ref);
  r.ranges = test::writeText(dir / "named.csv", named);
  r.anchors = test::writeText(dir / "named_anchors.csv",
                              "id,x,y,z\n1C8D,-4,-4,0.4\n2,5,-4,2.2\n6E44,5,5,1.5\n4,-4,5,2.6\n");
  r.tag_names["left"] = tag;
  const auto s = data::importCsv(r, (dir / "named").string());
  EXPECT_EQ(test::readText(dir / "named" / "ids.csv"),
            "kind,name,id\nanchor,1C8D,3\nanchor,6E44,5\ntag,left,0\n");
  std::string notes;
  for (const auto& n : s.notes) notes += n + "\n";
  EXPECT_NE(notes.find("ranges to anchors missing from " + r.anchors + ": 1 "), std::string::npos)
      << notes;
  EXPECT_NE(notes.find("anchors 1C8D = 3, 6E44 = 5; tags left = 0"), std::string::npos) << notes;
  const data::Dataset a = data::loadDataset(s.manifest, "");
  ASSERT_NE(uwb::findAnchor(a.anchors, 3), nullptr);
  EXPECT_EQ(uwb::findAnchor(a.anchors, 3)->position, Eigen::Vector3d(-4, -4, 0.4));

  data::CsvImportRequest q;
  q.reference = r.reference;
  q.ranges = test::writeText(dir / "numbered.csv", numbered);
  q.anchors = test::writeText(dir / "anchors.csv", test::kFourAnchors);
  q.tags[0] = tag;
  const data::Dataset b =
      data::loadDataset(data::importCsv(q, (dir / "numbered").string()).manifest, "");
  const auto ma = eval::evaluateMethod(a, "uwb-gn", 1, 1),
             mb = eval::evaluateMethod(b, "uwb-gn", 1, 1);
  std::printf("[ NAMES    ] uwb-gn rmse_2d %.6f m named, %.6f m numbered\n", ma.metrics.rmse_2d,
              mb.metrics.rmse_2d);
  EXPECT_EQ(ma.metrics.steps, mb.metrics.steps);
  EXPECT_NEAR(ma.metrics.rmse_2d, mb.metrics.rmse_2d, 1e-9);
  EXPECT_LT(ma.metrics.rmse_2d, 0.1);

  r.anchors = test::writeText(dir / "bad.csv", "1C8D,-4,-4,0.4\n3.5,5,-4,2.2\n");
  test::expectErrorMentions<data::InputError>([&] { data::importCsv(r, (dir / "bad").string()); },
                                              {"bad.csv:2", "'id'", "3.5"});
}

// A ranges file written one column per anchor, a row per epoch, as loggers and spreadsheets write
// it, reads as the same ranges written one a row: the columns matched to the anchors file's ids
// (alone, or after a word; a unit in brackets ignored), an empty, NaN or zero cell no range, a
// column of something else left out and said. Before, its header was an error ("must name the
// columns t, anchor_id and range").
TEST(CsvImport, RangesWrittenOneColumnPerAnchor) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d tag(0.0, 0.0, 0.8);
  const auto [ranges, ref] = test::driveACircle(tag, Eigen::Vector3d::Zero(), 0.0, true);
  std::string wide = "Time [s],range_1 [m],d2,Anchor 3,A-4,rssi_1\n";
  std::map<std::string, std::map<int, std::string>> epochs;  // t -> anchor -> range
  for (size_t a = ranges.find('\n') + 1, b; (b = ranges.find('\n', a)) != std::string::npos;
       a = b + 1) {
    const std::string line = ranges.substr(a, b - a);
    const size_t c1 = line.find(','), c2 = line.find(',', c1 + 1);
    epochs[line.substr(0, c1)][std::stoi(line.substr(c1 + 1, c2 - c1 - 1))] = line.substr(c2 + 1);
  }
  const char* const kNoRange[] = {"", "nan", "0", "-1"};
  int k = 0;
  for (const auto& [t, by_anchor] : epochs) {
    wide += t;
    for (int i = 1; i <= 4; ++i) {
      const auto it = by_anchor.find(i);
      wide += "," + (it != by_anchor.end() ? it->second : std::string(kNoRange[k++ % 4]));
    }
    wide += ",-80\n";
  }
  data::CsvImportRequest r;
  r.reference = test::writeText(dir / "ref.csv", ref);
  r.anchors = test::writeText(dir / "a.csv", test::kFourAnchors);
  r.tags[0] = tag;
  r.ranges = test::writeText(dir / "long.csv", ranges);
  const data::Dataset one_a_row =
      data::loadDataset(data::importCsv(r, (dir / "long").string()).manifest, "");
  r.ranges = test::writeText(dir / "wide.csv", wide);
  const auto s = data::importCsv(r, (dir / "wide").string());
  EXPECT_EQ(s.ranges, 300);
  EXPECT_EQ(s.skipped.at("range_empty_cell") + s.skipped.at("range_not_positive_cell"), 900);
  EXPECT_EQ(s.skipped.at("range_not_positive_cell"), 450);
  std::string notes;
  for (const auto& n : s.notes) notes += n + "\n";
  EXPECT_NE(notes.find("one column per anchor: 'range_1 [m]' anchor 1, 'd2' anchor 2, 'Anchor 3' "
                       "anchor 3, 'A-4' anchor 4; left out, naming no anchor of the anchors "
                       "file: 'rssi_1'"),
            std::string::npos)
      << notes;
  const data::Dataset one_a_column = data::loadDataset(s.manifest, "");
  ASSERT_EQ(one_a_column.events.size(), one_a_row.events.size());
  for (size_t i = 0; i < one_a_row.events.size(); ++i) {
    const auto* a = std::get_if<uwb::Range>(&one_a_row.events[i]);
    const auto* b = std::get_if<uwb::Range>(&one_a_column.events[i]);
    ASSERT_EQ(a == nullptr, b == nullptr) << i;
    if (!a) continue;
    EXPECT_EQ(a->t, b->t) << i;
    EXPECT_EQ(a->anchor_id, b->anchor_id) << i;
    EXPECT_EQ(a->range, b->range) << i;
  }
  // Anchors named in the anchors file, a tag column; two columns of one anchor, and none.
  r.reference.clear();
  r.anchors = test::writeText(dir / "named.csv", "name;X;Y;Z\nA1;0;0;1\nA2;8;0;1\nA3;0;8;1\n");
  r.ranges = test::writeText(dir / "named_wide.csv", "t,tag,A1,A2,A3\n1.0,0,3.2,5.8,5.1\n");
  const data::Dataset named =
      data::loadDataset(data::importCsv(r, (dir / "named").string()).manifest, "");
  std::vector<double> read;
  for (const auto& e : named.events)
    if (const auto* range = std::get_if<uwb::Range>(&e)) read.push_back(range->range);
  ASSERT_EQ(read.size(), 3u);
  for (size_t i = 0; i < 3; ++i) EXPECT_NEAR(read[i], (std::array{3.2, 5.8, 5.1})[i], 1e-6);
  r.ranges = test::writeText(dir / "twice.csv", "t,A1,range_a1\n1.0,3.2,3.2\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importCsv(r, (dir / "o").string()); },
      {"twice.csv:1", "'A1' and 'range_a1' both name anchor A1"});
  r.ranges = test::writeText(dir / "none.csv", "t,x,y\n1.0,3.2,3.2\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importCsv(r, (dir / "o").string()); },
      {"none.csv:1", "one column per anchor of the anchors file (A1, A2, A3)"});
}

// Anchors written without heights are taken at the tag's, loudly.
TEST(CsvImport, AnchorsWithoutHeightsAreAtTheTags) {
  const auto dir = test::scratchDir();
  data::CsvImportRequest r;
  r.anchors = test::writeText(dir / "a.csv", "id,x,y\n1,0,0\n2,8,0\n3,0,8\n");
  r.ranges = test::writeText(dir / "r.csv", "1.0,1,3\n1.0,2,5.8\n1.0,3,5.1\n");
  r.tags[0] = Eigen::Vector3d(0.1, 0.0, 0.75);
  const auto s = data::importCsv(r, (dir / "o").string());
  std::string notes;
  for (const auto& n : s.notes) notes += n + "\n";
  EXPECT_NE(notes.find("the anchors have no height (id,x,y): they are taken at the tag's, 0.75 m"),
            std::string::npos)
      << notes;
  const auto ds = data::loadDataset(s.manifest, "");
  ASSERT_EQ(ds.anchors.size(), 3u);
  for (const auto& a : ds.anchors) EXPECT_EQ(a.position.z(), 0.75);
  r.anchors = test::writeText(dir / "b.csv", "1,0,0\n2,8,0,1\n");
  test::expectErrorMentions<data::InputError>([&] { data::importCsv(r, (dir / "o2").string()); },
                                              {"b.csv:2", "3 fields like the first row"});
}

// Ranges from one tag that is not tag 0, and no --tag: that tag is the robot's (it was ignored by
// every method, uwb-ekf giving no estimate and the graph the odometry's). From two such tags: a
// warning at import and at loading that no range comes from the robot.
TEST(CsvImport, ALoneTagIsTheRobots) {
  const auto dir = test::scratchDir();
  const auto [ranges, ref] = test::driveACircle({0.0, 0.0, 0.8}, Eigen::Vector3d::Zero());
  const auto withTags = [&](int a, int b) {
    std::string out = "t,anchor_id,range,tag_id\n";
    int row = 0;
    for (size_t i = ranges.find('\n') + 1, j; (j = ranges.find('\n', i)) != std::string::npos;
         i = j + 1, ++row)
      out += ranges.substr(i, j - i) + "," + std::to_string(row % 2 ? a : b) + "\n";
    return out;
  };
  data::CsvImportRequest r;
  r.reference = test::writeText(dir / "ref.csv", ref);
  r.anchors = test::writeText(dir / "a.csv", test::kFourAnchors);
  r.tag_height = 0.8;
  r.ranges = test::writeText(dir / "five.csv", withTags(5, 5));
  auto s = data::importCsv(r, (dir / "five").string());
  std::string notes;
  for (const auto& n : s.notes) notes += n + "\n";
  EXPECT_NE(notes.find("from tag 5 alone: it is taken as the robot's"), std::string::npos) << notes;
  data::Dataset ds = data::loadDataset(s.manifest, "");
  EXPECT_TRUE(ds.warnings.empty()) << ds.warnings.front();
  const auto m = eval::evaluateMethod(ds, "uwb-gn", 1, 1);
  std::printf("[ TAG 5    ] uwb-gn rmse_2d %.4f m over %ld steps\n", m.metrics.rmse_2d,
              m.metrics.steps);
  EXPECT_GT(m.metrics.steps, 250);
  EXPECT_LT(m.metrics.rmse_2d, 0.1);

  r.ranges = test::writeText(dir / "two.csv", withTags(5, 7));
  s = data::importCsv(r, (dir / "two").string());
  notes.clear();
  for (const auto& n : s.notes) notes += n + "\n";
  EXPECT_NE(notes.find("the ranges come from tags 5, 7, none of them placed on the robot"),
            std::string::npos)
      << notes;
  ds = data::loadDataset(s.manifest, "");
  std::string warned;
  for (const auto& w : ds.warnings) warned += w + "\n";
  EXPECT_NE(warned.find("no range comes from a tag on the robot (the ranges' tags: 5, 7;"),
            std::string::npos)
      << warned;
}

// A robot driving curves among four anchors for 200 s (ranges to all four at 10 Hz with 5 cm of
// noise and one range in ten 2 m long; odometry increments at 10 Hz). Its odometry written with
// its y and turn negated, its turn in degrees or its distances in millimetres: import csv reads it
// the way that follows the ranges' own fixes, and says so; kept as written, loading names the
// reading. As written, or with a tenth of its turns off, nothing is said.
TEST(OdometryCheck, TheFixesNameAnOdometryWrittenInAnotherConvention) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d at[] = {{-6, -6, 2.0}, {7, -6, 2.5}, {7, 7, 1.8}, {-6, 7, 2.2}};
  const std::string anchors =
      test::writeText(dir / "a.csv", "1,-6,-6,2.0\n2,7,-6,2.5\n3,7,7,1.8\n4,-6,7,2.2\n");
  std::string ranges = "t,anchor_id,range\n";
  std::vector<std::pair<double, Eigen::Vector3d>> increments;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  Eigen::Vector3d pose(-3.0, -2.0, 0.3);
  char buf[120];
  for (int k = 0; k < 2000; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector3d delta(0.08, 0.0, 0.05 * std::sin(0.05 * t) + 0.03 * std::sin(0.31 * t));
    pose = composePose(pose, delta);
    increments.emplace_back(t, delta);
    for (int i = 0; i < 4; ++i) {
      const double r = (at[i] - Eigen::Vector3d(pose.x(), pose.y(), 0.5)).norm() + noise(rng) +
                       ((k + i) % 10 == 0 ? 2.0 : 0.0);
      std::snprintf(buf, sizeof buf, "%.3f,%d,%.4f\n", t + 0.001 * (i + 1), i + 1, r);
      ranges += buf;
    }
  }
  data::CsvImportRequest r;
  r.ranges = test::writeText(dir / "r.csv", ranges);
  r.anchors = anchors;
  r.tag_height = 0.5;
  // The odometry with its columns multiplied by `scale`, imported as `convention`: the import's
  // warning about it and loading's.
  const auto import = [&](const Eigen::Vector3d& scale, const std::string& convention) {
    std::string odometry = "t,dx,dy,dtheta\n";
    for (const auto& [t, d] : increments) {
      std::snprintf(buf, sizeof buf, "%.3f,%.6f,%.6f,%.8f\n", t, d.x() * scale.x(),
                    d.y() * scale.y(), d.z() * scale.z());
      odometry += buf;
    }
    r.odometry = test::writeText(dir / "o.csv", odometry);
    r.odometry_convention = convention;
    std::string said;
    const auto s = data::importCsv(r, (dir / "out").string());
    for (const auto& n : s.notes)
      if (n.find("odometry") != std::string::npos) said += n + "\n";
    for (const auto& w : data::loadDataset(s.manifest, "").warnings) said += w + "\n";
    return said;
  };
  EXPECT_EQ(import({1, 1, 1}, "auto"), "");
  EXPECT_EQ(import({1, 1, 1.1}, "auto"), "");
  const auto named = [&](const Eigen::Vector3d& scale, const char* reading) {
    const std::string read = import(scale, "auto");
    std::printf("[ ODOMETRY ] %s", read.c_str());
    EXPECT_NE(read.find(std::string("odometry read ") + reading), std::string::npos) << read;
    EXPECT_EQ(read.find("does not follow", read.find('\n')), std::string::npos) << read;
    const std::string kept = import(scale, "as-written");
    EXPECT_NE(kept.find(std::string("but does ") + reading), std::string::npos) << kept;
    EXPECT_NE(kept.find("--odometry-convention"), std::string::npos) << kept;
  };
  named({1, -1, -1}, "with its y and turn negated");
  named({1, 1, 180.0 / M_PI}, "with its turn in degrees");
  named({1000, 1000, 1}, "with its distances in millimetres");
}

// Every range written twice (a log concatenated, a topic recorded twice): loading drops the
// copies, counts and says so, and the methods score as on the ranges written once (the MRPT
// demo doubled gave uwb-ekf 0.769 m against 0.165 m). The same value at another stamp, or from
// another tag, is kept.
TEST(CsvImport, ARangeWrittenTwiceCountsOnce) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d tag(0.0, 0.0, 0.8);
  const auto [ranges, ref] = test::driveACircle(tag, Eigen::Vector3d::Zero());
  std::string doubled = "t,anchor_id,range\n";
  long rows = 0;
  for (size_t a = ranges.find('\n') + 1, b; (b = ranges.find('\n', a)) != std::string::npos;
       a = b + 1, ++rows) {
    const std::string line = ranges.substr(a, b - a + 1);
    doubled += line + line;
  }
  std::filesystem::create_directories(dir / "once");
  std::filesystem::create_directories(dir / "twice");
  const data::Dataset once =
      data::loadDataset(importDrive(dir / "once", ranges, ref, tag, false), "");
  const data::Dataset twice =
      data::loadDataset(importDrive(dir / "twice", doubled, ref, tag, false), "");
  EXPECT_EQ(twice.counts.at("rejected_duplicate_range"), rows);
  EXPECT_EQ(once.counts.count("rejected_duplicate_range"), 0u);
  EXPECT_EQ(twice.events.size(), once.events.size());
  std::string warned;
  for (const auto& w : twice.warnings) warned += w + "\n";
  EXPECT_NE(warned.find(std::to_string(rows) + " messages rejected at reading (duplicate_range)"),
            std::string::npos)
      << warned;
  for (const char* m : {"uwb-ekf", "uwb-kf"}) {
    const auto a = eval::evaluateMethod(once, m, 1, 1), b = eval::evaluateMethod(twice, m, 1, 1);
    std::printf("[ TWICE    ] %-7s rmse_2d %.6f m once, %.6f m written twice\n", m,
                a.metrics.rmse_2d, b.metrics.rmse_2d);
    EXPECT_EQ(a.metrics.rmse_2d, b.metrics.rmse_2d) << m;
  }
  // The same value at the next stamp, and from a second tag at the same stamp: kept.
  data::CsvImportRequest r;
  r.ranges = test::writeText(dir / "same.csv", "1.0,1,5.0,0\n1.1,1,5.0,0\n1.1,1,5.0,1\n");
  r.anchors = test::writeText(dir / "a.csv", test::kFourAnchors);
  const data::Dataset same =
      data::loadDataset(data::importCsv(r, (dir / "same").string()).manifest, "");
  EXPECT_EQ(same.events.size(), 3u);
}

TEST(CsvImport, TimeAndRangeUnitsFromTheData) {
  const auto dir = test::scratchDir();
  const std::string anchors = test::writeText(dir / "a.csv", kThreeAnchors);
  // The ranges with stamps t0 + 0.1 k s and the reference, in the given units.
  const auto write = [&](const std::string& name, double t0, double per_second, double per_metre,
                         double ref_per_second) {
    std::string ranges = "t,anchor_id,range\n", ref;
    char buf[160];
    driveAmongThreeAnchors(
        t0,
        [&](double t, int a, double r) {
          std::snprintf(buf, sizeof buf, "%.6f,%d,%.9g\n", t * per_second, a, r * per_metre);
          ranges += buf;
        },
        [&](double t, double x, double y) {
          std::snprintf(buf, sizeof buf, "%.6f %.4f %.4f\n", t * ref_per_second, x, y);
          ref += buf;
        });
    data::CsvImportRequest r;
    r.ranges = test::writeText(dir / (name + "_r.csv"), ranges);
    r.anchors = anchors;
    r.reference = test::writeText(dir / (name + "_ref.txt"), ref);
    r.tag_height = 1.0;
    return r;
  };
  const auto noted = [](const data::ImportSummary& s, const std::string& what) {
    for (const auto& n : s.notes)
      if (n.find("WARNING") != std::string::npos && n.find(what) != std::string::npos) return true;
    return false;
  };
  const double t0 = 1.7e9;  // 2023, in seconds since the epoch
  const auto ms_mm = write("ms_mm", t0, 1e3, 1e3, 1e9);
  const auto s = data::importCsv(ms_mm, (dir / "ms_mm").string());
  EXPECT_EQ(s.ranges, 300);
  EXPECT_TRUE(noted(s, "milliseconds"));
  EXPECT_TRUE(noted(s, "millimetres"));
  EXPECT_TRUE(noted(s, "nanoseconds"));  // the reference's
  const auto ds = data::loadDataset(s.manifest, "");
  EXPECT_NEAR(ds.ground_truth.front().t, t0, 1e-3);
  EXPECT_LT(eval::evaluateMethod(ds, "uwb-gn", 1, 1).metrics.rmse_2d, 1e-3);
  const auto us_cm = data::importCsv(write("us_cm", t0, 1e6, 1e2, 1.0), (dir / "us").string());
  EXPECT_TRUE(noted(us_cm, "microseconds"));
  EXPECT_TRUE(noted(us_cm, "centimetres"));
  EXPECT_FALSE(noted(us_cm, "nanoseconds"));
  EXPECT_LT(
      eval::evaluateMethod(data::loadDataset(us_cm.manifest, ""), "uwb-gn", 1, 1).metrics.rmse_2d,
      1e-3);
  // Seconds and metres as they are: no warning.
  for (const auto& n :
       data::importCsv(write("s_m", t0, 1.0, 1.0, 1.0), (dir / "sm").string()).notes)
    EXPECT_EQ(n.find("WARNING"), std::string::npos) << n;

  auto seconds = ms_mm;
  seconds.time_unit = "s";
  test::expectErrorMentions<data::InputError>(
      [&] { data::importCsv(seconds, (dir / "s").string()); },
      {"ms_mm_ref.txt:1", "absurd_time", "--time-unit"});
  seconds.reference.clear();
  test::expectErrorMentions<data::InputError>(
      [&] { data::importCsv(seconds, (dir / "s").string()); },
      {"ms_mm_r.csv", "no usable range", "range_absurd_time 300", "--time-unit"});
  auto far = write("far", t0, 1.0, 1e4, 1.0);  // neither cm (over 24 m) nor mm (under 0.8 m)
  test::expectErrorMentions<data::InputError>([&] { data::importCsv(far, (dir / "f").string()); },
                                              {"far_r.csv", "--range-unit"});
  far.range_unit = "mm";
  EXPECT_EQ(data::importCsv(far, (dir / "f").string()).ranges, 300);
  const auto from_zero = write("zero", 0.0, 1e4, 1.0, 1e4);  // 0.1 s read as 1000 s
  EXPECT_TRUE(noted(data::importCsv(from_zero, (dir / "z").string()), "--time-unit ms"));
}

// A tag away from the robot's origin, imported without saying where: the reference shows it, and
// a warning names the place and the --tag that sets it (ranges with a bias per anchor and one in
// eight 1.5 m long: neither moves the fit). Given there, no warning; with no reference, a note
// says what was assumed.
TEST(CsvImport, WarnsWhereTheRangesPlaceTheTagElsewhere) {
  const auto dir = test::scratchDir();
  const std::string anchors = test::writeText(dir / "a.csv", test::kFourAnchors);
  const Eigen::Vector3d tag(0.25, -0.15, 0.8);
  const auto [ranges, ref] = test::driveACircle(tag, Eigen::Vector3d::Zero());
  data::CsvImportRequest r;
  r.ranges = test::writeText(dir / "r.csv", ranges);
  r.anchors = anchors;
  r.reference = test::writeText(dir / "ref.csv", ref);
  const auto warnings = [&](const data::CsvImportRequest& req) {
    std::string w;
    for (const auto& n : data::importCsv(req, (dir / "out").string()).notes)
      if (n.find("WARNING") != std::string::npos) w += n + "\n";
    return w;
  };
  const std::string none_given = warnings(r);
  EXPECT_NE(none_given.find("r.csv"), std::string::npos) << none_given;
  EXPECT_NE(none_given.find("--tag 0,0.25,-0.15,0.80"), std::string::npos) << none_given;
  r.tag_height = 0.8;  // the height alone: the lever arm still wrong
  EXPECT_NE(warnings(r).find("--tag 0,0.25,-0.15,0.80"), std::string::npos);
  r.tags[0] = tag;
  EXPECT_EQ(warnings(r), "");
  // An anchor 1 000 km up (a typo): the height search is bounded, the import ends.
  r.anchors = test::writeText(dir / "far.csv", "1,-4,-4,0.4\n2,5,-4,2.2\n3,5,5,1.5\n4,-4,5,1e6\n");
  r.tags.clear();
  EXPECT_GT(data::importCsv(r, (dir / "far").string()).ranges, 0);
  r.anchors = anchors;
  r.tags.clear(), r.tag_height.reset(), r.reference.clear();
  bool noted = false;
  for (const auto& n : data::importCsv(r, (dir / "out").string()).notes)
    noted |= n.find("No tag position given") != std::string::npos;
  EXPECT_TRUE(noted);
}

// A reference whose clock lags the ranges' by 0.3 s: loading says so and gives the manifest
// line; with it the warning is gone.
TEST(CsvImport, WarnsWhenTheReferencesClockLags) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d tag(0.0, 0.0, 0.8);
  const auto [ranges, ref] = test::driveACircle(tag, Eigen::Vector3d::Zero(), 0.3);
  const std::string manifest = importDrive(dir, ranges, ref, tag, false);
  const std::string w = warningAbout(manifest, "clock");
  std::printf("[ CLOCK    ] %s\n", w.c_str());
  const std::string key = "gt_time_offset = ";
  ASSERT_NE(w.find(key), std::string::npos) << w;
  const double offset = std::stod(w.substr(w.find(key) + key.size()));
  EXPECT_NEAR(offset, 0.3, 0.02);
  std::string text = test::readText(manifest);
  text.replace(text.find("[dataset]"), 9, "[dataset]\n" + key + std::to_string(offset));
  test::writeText(manifest, text);
  EXPECT_EQ(warningAbout(manifest, "clock"), "");
  EXPECT_EQ(w.find("Or the tag sits"), std::string::npos) << w;  // its rate varies: a lag
}

// A reference whose clock counts from another origin (here two hours and 0.3 s ahead of the
// ranges', beginning 5 s after them and ending 3 s before): it covers none of the recording, and
// the warnings give the shift at which the ranges fit it. Stated in the manifest, the reference
// covers the recording. A robot that stands still fits every shift alike: no shift is offered.
TEST(CsvImport, FindsTheShiftOfAReferenceClockedFromAnotherOrigin) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d tag(0.0, 0.0, 0.8);
  const auto [ranges, full_ref] = test::driveACircle(tag, Eigen::Vector3d::Zero(), -7200.3);
  std::vector<std::string> rows;
  for (size_t a = 0, b; (b = full_ref.find('\n', a)) != std::string::npos; a = b + 1)
    rows.push_back(full_ref.substr(a, b - a + 1));
  std::string ref = rows.front();  // the header
  for (size_t k = 1 + 50; k + 30 < rows.size(); ++k) ref += rows[k];
  const std::string manifest = importDrive(dir, ranges, ref, tag, false);
  data::Dataset ds = data::loadDataset(manifest, "");
  ASSERT_TRUE(ds.reference_shift.has_value());
  EXPECT_NEAR(ds.reference_shift->shift, -7200.3, 0.02);
  EXPECT_LT(ds.reference_shift->departure, 0.05);
  const auto w = data::referenceCoverageWarning(ds);
  ASSERT_TRUE(w.has_value());
  std::printf("[ SHIFT    ] %s\n", w->c_str());
  const std::string key = "gt_time_offset = ";
  ASSERT_NE(w->find(key), std::string::npos) << *w;
  const double offset = std::stod(w->substr(w->find(key) + key.size()));
  EXPECT_NEAR(offset, -7200.3, 0.02);
  std::string text = test::readText(manifest);
  text.replace(text.find("[dataset]"), 9, "[dataset]\n" + key + std::to_string(offset));
  test::writeText(manifest, text);
  ds = data::loadDataset(manifest, "");
  EXPECT_FALSE(data::referenceCoverageWarning(ds).has_value());
  EXPECT_FALSE(ds.reference_shift.has_value());

  // Standing still at (1, 0.5) for 30 s, the reference stamped from zero.
  const Eigen::Vector3d at[] = {{-4, -4, 0.4}, {5, -4, 2.2}, {5, 5, 1.5}, {-4, 5, 2.6}};
  std::string still = "t,anchor_id,range\n", still_ref = "t,x,y,theta\n";
  char buf[120];
  for (int k = 0; k < 300; ++k) {
    for (int i = 0; i < 4; ++i) {
      std::snprintf(buf, sizeof buf, "%.2f,%d,%.6f\n", 1000.0 + 0.1 * k, i + 1,
                    (Eigen::Vector3d(1.0, 0.5, 0.8) - at[i]).norm() + 0.02 * ((k + i) % 3));
      still += buf;
    }
    std::snprintf(buf, sizeof buf, "%.2f,1.0,0.5,0.0\n", 0.1 * k);
    still_ref += buf;
  }
  ds = data::loadDataset(importDrive(dir, still, still_ref, tag, false), "");
  EXPECT_TRUE(data::referenceCoverageWarning(ds).has_value());
  EXPECT_FALSE(ds.reference_shift.has_value());
}

// A tag 0.3 m ahead of the reference point on a robot driving up and down a line at 1 m/s: a lag
// of the reference's clock explains the ranges, and so does the lever arm; the warning gives
// both, and the lever arm stated, the ranges agree.
TEST(CsvImport, SaysALagAndALeverArmAlongTheTravelReadAlike) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d at[] = {{-4, -4, 0.4}, {5, -4, 2.2}, {5, 5, 1.5}, {-4, 5, 2.6}};
  const Eigen::Vector3d tag(0.3, 0.0, 0.8);
  std::string ranges = "t,anchor_id,range\n", ref = "t,x,y,theta\n";
  char buf[160];
  for (int k = 0; k < 400; ++k) {
    const double t = 10.0 + 0.1 * k, s = std::fmod(0.1 * k, 12.0);  // 6 m out, 6 m back
    const Eigen::Vector3d pose(s < 6.0 ? s - 3.0 : 9.0 - s, 0.5, s < 6.0 ? 0.0 : M_PI);
    for (int i = 0; i < 4; ++i) {
      std::snprintf(buf, sizeof buf, "%.2f,%d,%.6f\n", t, i + 1,
                    (uwb::tagPosition(pose, tag) - at[i]).norm());
      ranges += buf;
    }
    std::snprintf(buf, sizeof buf, "%.2f,%.4f,%.4f,%.6f\n", t, pose.x(), pose.y(), pose.z());
    ref += buf;
  }
  const std::string manifest = importDrive(dir, ranges, ref, tag, true);
  const std::string w = warningAbout(manifest, "clock");
  std::printf("[ CLOCK    ] %s\n", w.c_str());
  EXPECT_NE(w.find("gt_time_offset = -0.300"), std::string::npos) << w;
  EXPECT_NE(w.find("Or the tag sits at (0.30, 0.00) m on the robot"), std::string::npos) << w;
  EXPECT_NE(w.find("lever_arm_x = 0.30 and lever_arm_y = 0.00"), std::string::npos) << w;
  std::string text = test::readText(manifest);
  text.replace(text.find("[tag]"), 5, "[tag]\nlever_arm_x = 0.30\nlever_arm_y = 0.00");
  test::writeText(manifest, text);
  EXPECT_EQ(warningAbout(manifest, "clock"), "");
}

namespace {

// The reference's y and heading negated: `t,x,y,theta` rows, or TUM's `t x y z qx qy qz qw`.
std::string mirrored(const std::string& reference) {
  std::istringstream in(reference);
  std::string out;
  for (std::string line; std::getline(in, line);) {
    const bool tum = line.find(',') == std::string::npos;
    std::vector<std::string> f;
    std::istringstream row(line);
    for (std::string v;
         tum ? static_cast<bool>(row >> v) : static_cast<bool>(std::getline(row, v, ','));)
      f.push_back(v);
    if (f.size() >= 4 && f[0] != "t" && f[0][0] != '#')
      for (size_t k : tum ? std::vector<size_t>{2, 6} : std::vector<size_t>{2, 3})
        f[k] = std::to_string(-std::stod(f[k]));
    for (size_t k = 0; k < f.size(); ++k) out += (k ? (tum ? " " : ",") : "") + f[k];
    out += "\n";
  }
  return out;
}

// A circle drive imported into `dir` with its reference moved by `frame` (then mirrored when
// `mirror`): its manifest. Its ranges one anchor at a time when `one_at_a_time`; with
// `odometry`, the robot's poses (never mirrored) as its odometry.
std::string importCircle(const std::filesystem::path& dir, const std::string& name,
                         const std::string& anchors, const Eigen::Vector3d& frame,
                         bool one_at_a_time, bool mirror = false, bool odometry = false) {
  const Eigen::Vector3d tag(0.0, 0.0, 0.8);
  auto [ranges, ref] = test::driveACircle(tag, frame, 0.0, one_at_a_time);
  data::CsvImportRequest r;
  if (odometry) {
    r.odometry = test::writeText(dir / (name + "_odo.csv"), ref);
    r.odometry_kind = "poses";
  }
  if (mirror) ref = mirrored(ref);
  r.ranges = test::writeText(dir / (name + "_r.csv"), ranges);
  r.anchors = test::writeText(dir / (name + "_a.csv"), anchors);
  r.reference = test::writeText(dir / (name + "_ref.csv"), ref);
  r.tags[0] = tag;
  return data::importCsv(r, (dir / name).string()).manifest;
}

std::string disagreement(const data::Dataset& ds) {
  for (const auto& w : ds.warnings)
    if (w.find("disagree with the reference") != std::string::npos) return w;
  return std::string();
}

// The frame line of warning `w` is the inverse of `frame` (the reference's frame seen from the
// anchors'), within 0.05 m and 0.5 deg; written into `manifest`. False when `w` has none.
bool stateTheFrame(const std::string& manifest, const std::string& w,
                   const Eigen::Vector3d& frame) {
  const std::string key = "gt_origin_in_anchor_frame = ";
  if (w.find(key) == std::string::npos) {
    ADD_FAILURE() << w;
    return false;
  }
  double x = 0, y = 0, yaw_deg = 0;
  std::istringstream(w.substr(w.find(key) + key.size())) >> x >> y >> yaw_deg;
  const Eigen::Vector3d inverse = relativePose(frame, Eigen::Vector3d::Zero());
  EXPECT_NEAR(x, inverse.x(), 0.05);
  EXPECT_NEAR(y, inverse.y(), 0.05);
  EXPECT_NEAR(yaw_deg, inverse.z() * 180.0 / M_PI, 0.5);
  std::string text = test::readText(manifest);
  text.replace(text.find("[anchors]"), 9, "[anchors]\n" + key + w.substr(w.find(key) + key.size()));
  test::writeText(manifest, text);
  return true;
}

// The warning on a reference moved by `frame` (and mirrored when `mirror`) states the frame's
// inverse, and once the manifest states it (and the reference is mirrored back) the ranges agree
// with the reference. The manifest with it in.
std::string expectTheFrameStated(const std::string& manifest, const Eigen::Vector3d& frame,
                                 const std::string& fit_by, bool mirror = false) {
  const std::string w = disagreement(data::loadDataset(manifest, ""));
  std::printf("[ FRAME    ] %s\n", w.c_str());
  EXPECT_NE(w.find("The " + fit_by + " fit the reference" + (mirror ? " mirrored" : " after")),
            std::string::npos)
      << w;
  if (!stateTheFrame(manifest, w, frame)) return manifest;
  if (mirror) {
    const auto reference = std::filesystem::path(manifest).parent_path() / "ground_truth.tum";
    test::writeText(reference, mirrored(test::readText(reference)));
  }
  EXPECT_EQ(disagreement(data::loadDataset(manifest, "")), "");
  return manifest;
}

// The drive with its reference in the anchors' frame: no disagreement.
void expectNoWarningOnTheRightData(const std::filesystem::path& dir, bool one_at_a_time) {
  EXPECT_EQ(disagreement(data::loadDataset(importCircle(dir, "right", test::kFourAnchors,
                                                        Eigen::Vector3d::Zero(), one_at_a_time),
                                           "")),
            "");
}

}  // namespace

// A reference in another frame than the anchors (turned 25 deg and moved 2.5 m): loading says
// so and gives the manifest line that states it, and with that line the ranges agree and the
// warning is gone. Two anchors with their ids swapped: no rigid motion explains the ranges,
// and the warning says what to check (not two across the diagonal of the square: those, heights
// and all, are its mirror image, as a mirrored reference would be). The right data: no warning.
TEST(CsvImport, WarnsWhenTheReferenceIsInAnotherFrame) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d frame(2.0, -1.5, 25.0 * M_PI / 180.0);
  const std::string manifest = expectTheFrameStated(
      importCircle(dir, "moved", test::kFourAnchors, frame, false), frame, "multilateration fixes");
  EXPECT_LT(eval::evaluateMethod(data::loadDataset(manifest, ""), "uwb-gn", 1, 1).metrics.rmse_2d,
            0.1);

  const auto swapped = data::loadDataset(
      importCircle(dir, "swapped", "1,5,-4,2.2\n2,-4,-4,0.4\n3,5,5,1.5\n4,-4,5,2.6\n",
                   Eigen::Vector3d::Zero(), false),
      "");
  const std::string sw = disagreement(swapped);
  std::printf("[ FRAME    ] %s\n", sw.c_str());
  EXPECT_NE(sw.find("No rigid motion"), std::string::npos) << sw;
  EXPECT_NE(sw.find("anchors' coordinates and ids"), std::string::npos) << sw;
  expectNoWarningOnTheRightData(dir, false);
}

// A reference in a left-handed frame: its y and heading negated.
TEST(CsvImport, WarnsWhenTheReferenceIsMirrored) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d frame(1.0, 2.0, 60.0 * M_PI / 180.0);
  expectTheFrameStated(importCircle(dir, "mirrored", test::kFourAnchors, frame, false, true), frame,
                       "multilateration fixes", true);
  expectTheFrameStated(importCircle(dir, "mirrored1", test::kFourAnchors, frame, true, true), frame,
                       "ranges", true);
}

// Which of the two is left-handed, told by the odometry (right-handed, as robots report it):
// with the reference mirrored it turns against the reference, and the warning says to mirror the
// reference back; with the anchors mirrored (their y negated) it turns with the reference, and
// the warning says to negate the anchors' y and gives the frame that then holds. Either fix
// stated, the ranges agree. Without odometry the warning says the ranges cannot tell.
TEST(CsvImport, TheOdometryTellsWhetherTheReferenceOrTheAnchorsAreMirrored) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d frame(1.0, 2.0, 60.0 * M_PI / 180.0);
  const std::string reference_mirrored =
      importCircle(dir, "ref", test::kFourAnchors, frame, false, true, true);
  const std::string rw = disagreement(data::loadDataset(reference_mirrored, ""));
  EXPECT_NE(rw.find("the reference left-handed"), std::string::npos) << rw;
  EXPECT_NE(rw.find("write the reference with its y and heading negated"), std::string::npos);
  expectTheFrameStated(reference_mirrored, frame, "multilateration fixes", true);

  const std::string anchors_mirrored =
      importCircle(dir, "anchors", "1,-4,4,0.4\n2,5,4,2.2\n3,5,-5,1.5\n4,-4,-5,2.6\n", frame, false,
                   false, true);
  const std::string w = disagreement(data::loadDataset(anchors_mirrored, ""));
  std::printf("[ FRAME    ] %s\n", w.c_str());
  EXPECT_NE(w.find("the anchors left-handed: the odometry turns with the reference"),
            std::string::npos)
      << w;
  EXPECT_NE(w.find("write the anchors with their y negated"), std::string::npos) << w;
  ASSERT_TRUE(stateTheFrame(anchors_mirrored, w, frame));
  const auto folder = std::filesystem::path(anchors_mirrored).parent_path();
  test::writeText(folder / "anchors.csv", std::string("id,x,y,z\n") + test::kFourAnchors);
  EXPECT_EQ(disagreement(data::loadDataset(anchors_mirrored, "")), "");

  const std::string no_odometry = disagreement(
      data::loadDataset(importCircle(dir, "none", test::kFourAnchors, frame, false, true), ""));
  EXPECT_NE(no_odometry.find("the ranges cannot tell which"), std::string::npos) << no_odometry;
}

// Ranges that come one anchor at a time give no multilateration fix; the frame is found from the
// ranges themselves.
TEST(CsvImport, WarnsWhenTheReferenceIsInAnotherFrameWithOneAnchorAtATime) {
  const auto dir = test::scratchDir();
  const Eigen::Vector3d frame(-3.0, 1.0, -140.0 * M_PI / 180.0);
  expectTheFrameStated(importCircle(dir, "moved1", test::kFourAnchors, frame, true), frame,
                       "ranges");
  expectNoWarningOnTheRightData(dir, true);
}

// The triangle inequality on two ranges of one tag, by hand: anchors 10 m apart; ranges of 4 m
// and 4 m taken together fall short (8 + 0.5 < 10); 4.8 and 4.8 do not (9.6 + 0.5 > 10); 4 and
// 4.5 and 4.5 do (9 + 0.5 < 10), but not taken 0.4 s apart (the tag may have moved 1.2 m:
// 9 + 1.7 > 10); 0.6 s apart they are no pair. Ranges of 9.6 and 0.9 m are long (8.7 > 5.5) with
// the anchors read 5 m apart.
TEST(RangeGeometry, PairsOfRangesAgainstTheAnchorsDistanceApart) {
  const std::vector<uwb::Anchor> anchors = {{1, {0, 0, 1}}, {2, {6, 8, 1}}};
  const auto pairs = [&](std::vector<std::tuple<double, int, double>> ranges, double scale) {
    std::vector<loc::Event> events;
    for (const auto& [t, a, r] : ranges) {
      uwb::Range m;
      m.t = t, m.anchor_id = a, m.range = r;
      events.emplace_back(m);
    }
    return data::checkRangePairs(events, anchors, scale);
  };
  auto p = pairs({{0.0, 1, 4.0}, {0.0, 2, 4.0}}, 1.0);
  EXPECT_EQ(p.pairs, 1);
  EXPECT_EQ(p.short_pairs, 1);
  EXPECT_DOUBLE_EQ(p.median_shortfall, 2.0);
  EXPECT_EQ(p.per_anchor.at(1), std::make_pair(1L, 1L));
  EXPECT_EQ(pairs({{0.0, 1, 4.8}, {0.0, 2, 4.8}}, 1.0).short_pairs, 0);
  EXPECT_EQ(pairs({{0.0, 1, 4.5}, {0.0, 2, 4.5}}, 1.0).short_pairs, 1);
  p = pairs({{0.0, 1, 4.5}, {0.4, 2, 4.5}}, 1.0);
  EXPECT_EQ(p.pairs, 1);
  EXPECT_EQ(p.short_pairs, 0);
  EXPECT_EQ(pairs({{0.0, 1, 4.0}, {0.6, 2, 4.0}}, 1.0).pairs, 0);
  p = pairs({{0.0, 1, 9.6}, {0.0, 2, 0.9}}, 0.5);
  EXPECT_EQ(p.long_pairs, 1);
  EXPECT_EQ(p.short_pairs, 0);
  EXPECT_EQ(pairs({{0.0, 1, 9.6}, {0.0, 2, 0.9}}, 1.0).long_pairs, 0);
}

namespace {
std::string geometryWarning(const data::Dataset& ds) {
  for (const auto& w : ds.warnings)
    if (w.find("cannot be distances") != std::string::npos) return w;
  return std::string();
}
}  // namespace

// Anchors written in millimetres or feet beside ranges in metres: no tag position gives the
// ranges (two of them together fall short of their anchors' distance apart), so the import reads
// the anchors in the one unit that fits, loudly, and the recording scores as the one in metres.
// Asked to take them as metres, it does, and loading names the unit that would fit. One anchor
// written 10 times too far (a typo): loading names it and leaves its ranges out, and the other
// three place the tag. Ranges and anchors both in millimetres (a median range of kilometres,
// among anchors as far apart) are refused, naming the options, and read with them; the ranges in
// millimetres taken as metres are named too long, with the unit that fits. The right data: none of
// these warnings.
TEST(CsvImport, AnchorsInAnotherUnitOrPlaceThanTheRanges) {
  const auto dir = test::scratchDir();
  const auto [ranges, ref] = test::driveACircle(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  const auto import = [&](const std::string& name, const std::string& anchors,
                          const std::string& range_text, const std::string& anchor_unit = "auto",
                          const std::string& range_unit = "auto") {
    data::CsvImportRequest r;
    r.ranges = test::writeText(dir / (name + "_r.csv"), range_text);
    r.anchors = test::writeText(dir / (name + "_a.csv"), anchors);
    r.reference = test::writeText(dir / (name + "_ref.csv"), ref);
    r.anchor_unit = anchor_unit;
    r.range_unit = range_unit;
    return data::importCsv(r, (dir / name).string());
  };
  const auto warned = [](const data::ImportSummary& s, const std::string& what) {
    for (const auto& n : s.notes)
      if (n.find("WARNING") != std::string::npos && n.find(what) != std::string::npos) return true;
    return false;
  };
  const auto expectMetres = [](const data::Dataset& ds) {
    ASSERT_EQ(ds.anchors.size(), 4u);
    EXPECT_NEAR(ds.anchors[1].position.x(), 5.0, 1e-9);
    EXPECT_NEAR(ds.anchors[1].position.z(), 2.2, 1e-9);
    EXPECT_EQ(geometryWarning(ds), "");
    EXPECT_LT(eval::evaluateMethod(ds, "uwb-gn", 1, 1).metrics.rmse_2d, 0.2);
  };
  const std::string mm =
      "1,-4000,-4000,400\n2,5000,-4000,2200\n3,5000,5000,1500\n4,-4000,5000,2600\n";
  const auto in_mm = import("mm", mm, ranges);
  EXPECT_TRUE(warned(in_mm, "anchors read as millimetres"));
  expectMetres(data::loadDataset(in_mm.manifest, ""));
  const std::string ft =
      "1,-13.12336,-13.12336,1.31234\n2,16.4042,-13.12336,7.21785\n3,16.4042,16.4042,4.92126\n"
      "4,-13.12336,16.4042,8.53018\n";
  const auto in_ft = import("ft", ft, ranges);
  EXPECT_TRUE(warned(in_ft, "anchors read as feet"));
  for (const auto& manifest : {in_ft.manifest, import("ft_given", ft, ranges, "ft").manifest}) {
    const auto ds = data::loadDataset(manifest, "");
    EXPECT_NEAR(ds.anchors[1].position.x(), 5.0, 1e-5);
    EXPECT_EQ(geometryWarning(ds), "");
  }
  const auto as_metres = import("as_m", mm, ranges, "m");
  EXPECT_FALSE(warned(as_metres, "anchors read as"));
  const std::string w = geometryWarning(data::loadDataset(as_metres.manifest, ""));
  std::printf("[ GEOMETRY ] %s\n", w.c_str());
  EXPECT_NE(w.find("read in millimetres, the anchors would fit them"), std::string::npos) << w;

  const auto typo = import("typo", "1,-4,-4,0.4\n2,5,-4,2.2\n3,5,5,1.5\n4,-40,5,2.6\n", ranges);
  EXPECT_FALSE(warned(typo, "anchors read as"));  // read in feet, it would fit
  const auto typo_ds = data::loadDataset(typo.manifest, "");
  const std::string tw = geometryWarning(typo_ds);
  std::printf("[ GEOMETRY ] %s\n", tw.c_str());
  EXPECT_NE(tw.find("the ranges of anchor 4 cannot"), std::string::npos) << tw;
  EXPECT_NE(tw.find("Check anchor 4's coordinates"), std::string::npos) << tw;
  EXPECT_NE(tw.find("its ranges are left out"), std::string::npos) << tw;
  ASSERT_EQ(typo_ds.anchors.size(), 3u);  // anchor 4 left out: the other three place the tag
  EXPECT_EQ(uwb::findAnchor(typo_ds.anchors, 4), nullptr);
  const auto typo_run = eval::evaluateMethod(typo_ds, "uwb-gn", 1, 1);
  EXPECT_LT(typo_run.metrics.rmse_2d, 0.2);
  EXPECT_GT(typo_run.rejected.at("unknown_anchor"), 0);

  std::string ranges_mm;
  {
    std::istringstream in(ranges);
    std::string line;
    std::getline(in, line);
    ranges_mm = line + "\n";
    while (std::getline(in, line)) {
      const auto c = line.rfind(',');
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.3f", 1000.0 * std::stod(line.substr(c + 1)));
      ranges_mm += line.substr(0, c + 1) + buf + "\n";
    }
  }
  test::expectErrorMentions<data::InputError>(
      [&] { import("both_mm", mm, ranges_mm); },
      {"both_mm_r.csv", "beyond any UWB link", "--range-unit", "--anchor-unit"});
  expectMetres(data::loadDataset(import("both_mm", mm, ranges_mm, "mm", "mm").manifest, ""));
  // The ranges in millimetres taken as metres: far too long for the anchors.
  const std::string lw = geometryWarning(data::loadDataset(
      import("ranges_mm", test::kFourAnchors, ranges_mm, "auto", "m").manifest, ""));
  std::printf("[ GEOMETRY ] %s\n", lw.c_str());
  EXPECT_NE(lw.find("differ by more than the anchors' distance apart"), std::string::npos) << lw;
  EXPECT_NE(lw.find("read in millimetres, the ranges would fit them"), std::string::npos) << lw;

  const auto right = import("right", test::kFourAnchors, ranges);
  for (const auto& n : right.notes) EXPECT_EQ(n.find("WARNING"), std::string::npos) << n;
  expectMetres(data::loadDataset(right.manifest, ""));
}

// A spreadsheet's export: a UTF-8 byte-order mark, semicolons, decimal commas, CRLF line ends
// and a header ending in a separator. It reads as the plain file does.
TEST(CsvImport, ASpreadsheetsSemicolonsAndDecimalCommas) {
  const auto dir = test::scratchDir();
  std::string plain = "t,anchor_id,range\n", sheet = "\xEF\xBB\xBFt;anchor_id;range;\r\n";
  char buf[160];
  driveAmongThreeAnchors(
      5.0,
      [&](double t, int a, double r) {
        std::snprintf(buf, sizeof buf, "%.2f,%d,%.6f\n", t, a, r);
        plain += buf;
        std::string row = buf;
        for (char& c : row) c = c == ',' ? ';' : c == '.' ? ',' : c;
        row.insert(row.size() - 1, ";\r");
        sheet += row;
      },
      [](double, double, double) {});
  data::CsvImportRequest r;
  r.anchors =
      test::writeText(dir / "a.csv", "\xEF\xBB\xBFid;x;y;z\r\n1;0;0;1\r\n2;8;0;1\r\n3;0;8,0;1\r\n");
  r.tag_height = 1.0;
  r.ranges = test::writeText(dir / "plain.csv", plain);
  const auto a = data::loadDataset(data::importCsv(r, (dir / "plain").string()).manifest, "");
  r.ranges = test::writeText(dir / "sheet.csv", sheet);
  const auto s = data::importCsv(r, (dir / "sheet").string());
  EXPECT_EQ(s.ranges, 300);
  const auto b = data::loadDataset(s.manifest, "");
  ASSERT_EQ(a.events.size(), b.events.size());
  for (size_t i = 0; i < a.events.size(); ++i) {
    const auto& ra = std::get<uwb::Range>(a.events[i]);
    const auto& rb = std::get<uwb::Range>(b.events[i]);
    EXPECT_EQ(ra.t, rb.t);
    EXPECT_EQ(ra.anchor_id, rb.anchor_id);
    EXPECT_EQ(ra.range, rb.range);
  }
  ASSERT_EQ(b.anchors.size(), 3u);
  EXPECT_EQ(b.anchors[2].position, Eigen::Vector3d(0, 8, 1));
}

// A scan that does not start at -aperture/2 keeps its rays' directions: the sensor turns by the
// scan's centre angle.
TEST(CsvImport, AnAsymmetricScanKeepsItsRayDirections) {
  const auto dir = test::scratchDir();
  test::writeText(dir / "a.csv", "1,0,0,1\n");
  test::writeText(dir / "r.csv", "1.0,1,3\n");
  data::CsvImportRequest r;
  r.ranges = (dir / "r.csv").string();
  r.anchors = (dir / "a.csv").string();
  r.scans = test::writeText(dir / "s.csv", "1.0,0.0,0.5,2,0,3,nan,4\n");
  r.scan_pose = Eigen::Vector3d(0.1, 0.0, 0.0);
  const auto s = data::importCsv(r, (dir / "out").string());
  EXPECT_EQ(s.scans, 1);
  const auto ds = data::loadDataset(s.manifest, "");
  std::vector<Eigen::Vector2d> points;
  for (const auto& e : ds.events)
    if (const auto* scan = std::get_if<loc::LaserScan>(&e)) {
      EXPECT_FLOAT_EQ(scan->max_range, 4.0f);
      loc::forEachScanEndpoint(*scan, 1, 0.0, 10.0,
                               [&](size_t, const Eigen::Vector2d& p) { points.push_back(p); });
    }
  ASSERT_EQ(points.size(), 3u);  // the rays reading 0 and nan did not return
  const double angles[] = {0.0, 1.0, 2.0}, ranges[] = {2.0, 3.0, 4.0};
  for (size_t i = 0; i < 3; ++i) {
    const Eigen::Vector2d expected =
        Eigen::Vector2d(0.1, 0) +
        ranges[i] * Eigen::Vector2d(std::cos(angles[i]), std::sin(angles[i]));
    EXPECT_LT((points[i] - expected).norm(), 1e-5) << i;
  }
}

TEST(CsvImport, MalformedRowsNameFileAndLine) {
  const auto dir = test::scratchDir();
  test::writeText(dir / "a.csv", "1,0,0,1\n");
  data::CsvImportRequest r;
  r.anchors = (dir / "a.csv").string();
  r.ranges = test::writeText(dir / "r.csv", "1.0,1,3\n1.1,1,abc\n");
  test::expectErrorMentions<data::InputError>([&] { data::importCsv(r, (dir / "o").string()); },
                                              {"r.csv:2", "range"});
  r.ranges = test::writeText(dir / "r2.csv", "1.0,1,3\n1.1,1\n");
  test::expectErrorMentions<data::InputError>([&] { data::importCsv(r, (dir / "o").string()); },
                                              {"r2.csv:2", "3 fields"});
  r.ranges = test::writeText(dir / "r3.csv", "time,station,range\n1.0,1,3\n");
  test::expectErrorMentions<data::InputError>([&] { data::importCsv(r, (dir / "o").string()); },
                                              {"r3.csv:1", "anchor_id"});
  // Rows with an unusable time or a non-finite range are skipped and counted.
  r.ranges = test::writeText(dir / "r4.csv", "1.0,1,3\n-5,1,3\n1.2,1,nan\n1.3,1,3\n");
  const auto s = data::importCsv(r, (dir / "o").string());
  EXPECT_EQ(s.ranges, 2);
  EXPECT_EQ(s.skipped.at("range_negative_time"), 1);
  EXPECT_EQ(s.skipped.at("range_non_finite"), 1);
}

// A libRSF text file written here (the format of its datasets' readme files): a robot driving a
// circle among four anchors, differential-drive odometry, ground truth in the _GT file beside.
TEST(LibrsfImport, ReadsRangesOdometryAndTheReferenceBeside) {
  const auto dir = test::scratchDir();
  const Eigen::Vector2d anchors[] = {{0, 0}, {6, 0}, {6, 6}, {0, 6}};
  const int ids[] = {105, 107, 108, 109};
  std::string input = "# comment\n", gt;
  const double radius = 2.0, v = 0.4, w = v / radius, base = 0.0785;
  for (int k = 0; k <= 300; ++k) {
    const double t = 0.128 * k, a = w * t;
    const Eigen::Vector2d p(3.0 + radius * std::sin(a), 1.0 + radius * (1 - std::cos(a)));
    char buf[200];
    const int i = k % 4;
    std::snprintf(buf, sizeof buf, "range2 %.6f %.9f 0.0025 %.3f %.3f %d 0\n", t,
                  (p - anchors[i]).norm(), anchors[i].x(), anchors[i].y(), ids[i]);
    input += buf;
    std::snprintf(buf, sizeof buf, "odom2diff %.6f %.9f %.9f 0 %.4f 0.0001 0.0001 0.0001\n", t,
                  v + w * base / 2, v - w * base / 2, base);
    input += buf;
    std::snprintf(buf, sizeof buf, "point2 %.6f %.9f %.9f 0 0 0 0\n", t, p.x(), p.y());
    gt += buf;
  }
  input += "imu3 1.0 0 0 0\n";
  const auto file = test::writeText(dir / "Loop_Input.txt", input);
  test::writeText(dir / "Loop_GT.txt", gt);
  const auto s = data::importLibrsf(file, (dir / "out").string());
  EXPECT_EQ(s.ranges, 301);
  EXPECT_EQ(s.anchors, 4);
  EXPECT_EQ(s.ground_truth_rows, 301);
  EXPECT_EQ(s.skipped.at("other_type_imu3"), 1);
  const auto ds = data::loadDataset(s.manifest, "");
  ASSERT_TRUE(ds.manifest.uwb_sigma.has_value());
  EXPECT_NEAR(*ds.manifest.uwb_sigma, 0.05, 1e-9);  // the square root of the variance field
  EXPECT_FALSE(ds.manifest.reference_heading);
  EXPECT_EQ(uwb::findAnchor(ds.anchors, 108)->position, Eigen::Vector3d(6, 6, 0));
  // Dead reckoning from the true start pose (heading 0) follows the circle.
  Eigen::Vector3d pose(3.0, 1.0, 0.0);
  for (const auto& e : ds.events)
    if (const auto* o = std::get_if<loc::OdometryIncrement>(&e)) pose = composePose(pose, o->delta);
  const double a_end = w * 0.128 * 300;
  EXPECT_LT((pose.head<2>() -
             Eigen::Vector2d(3.0 + radius * std::sin(a_end), 1.0 + radius * (1 - std::cos(a_end))))
                .norm(),
            1e-4);
  const auto m = eval::evaluateMethod(ds, "graph-uwb-odom", 1, 1);
  std::printf("[ LIBRSF   ] graph-uwb-odom rmse_2d %.4f m\n", m.metrics.rmse_2d);
  EXPECT_LT(m.metrics.rmse_2d, 0.05);
  // A malformed line is named.
  test::writeText(dir / "Bad_Input.txt", "range2 1.0 2.0 0.01 0 0\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importLibrsf((dir / "Bad_Input.txt").string(), (dir / "o2").string()); },
      {"Bad_Input.txt:1", "range2", "got 5 fields"});
  test::writeText(dir / "Moved_Input.txt",
                  "range2 1.0 2.0 0.01 0 0 7\nrange2 1.1 2.0 0.01 1 0 7\n");
  test::expectErrorMentions<data::InputError>(
      [&] { data::importLibrsf((dir / "Moved_Input.txt").string(), (dir / "o3").string()); },
      {"Moved_Input.txt:2", "anchor 7"});
}
