#include "uwbloc/dataset/plaza_import.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/dataset/rawlog.hpp"
#include "uwbloc/dataset/text_io.hpp"

namespace fs = std::filesystem;

namespace uwbloc::data {

ImportSummary importPlaza(const std::string& dir, const std::string& out_dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throwInputError(dir, 0, "folder not found");
  std::string prefix;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string n = e.path().filename().string();
    if (n.size() > 7 && n.rfind("_DR.txt") == n.size() - 7) prefix = n.substr(0, n.size() - 7);
  }
  if (prefix.empty()) throwInputError(dir, 0, "no Plaza*_DR.txt file");
  const auto file = [&](const char* suffix) {
    return (fs::path(dir) / (prefix + suffix)).string();
  };

  std::vector<loc::Event> events;
  const std::string dr = file("_DR.txt");
  forEachRow(dr, [&](int line, const std::vector<std::string>& f) {
    if (f.size() < 3) throwInputError(dr, line, "expected 't distance heading_change'");
    const double t = parseNumber(f[0], dr, line, "t"), d = parseNumber(f[1], dr, line, "distance"),
                 dh = parseNumber(f[2], dr, line, "heading_change");
    loc::OdometryIncrement o;
    o.t = t;
    o.delta << -d * std::cos(dh / 2), -d * std::sin(dh / 2), dh;
    events.emplace_back(o);
  });
  std::vector<uwb::Anchor> anchors;
  const std::string tl = file("_TL.txt");
  forEachRow(tl, [&](int line, const std::vector<std::string>& f) {
    if (f.size() < 3) throwInputError(tl, line, "expected 'id x y'");
    anchors.push_back({static_cast<int>(parseNumber(f[0], tl, line, "id")),
                       {parseNumber(f[1], tl, line, "x"), parseNumber(f[2], tl, line, "y"), 0.0}});
  });
  const std::string td = file("_TD.txt");
  long ranges = 0;
  forEachRow(td, [&](int line, const std::vector<std::string>& f) {
    if (f.size() < 4) throwInputError(td, line, "expected 't sender beacon range'");
    uwb::Range r;
    r.t = parseNumber(f[0], td, line, "t");
    r.anchor_id = static_cast<int>(parseNumber(f[2], td, line, "beacon"));
    r.range = parseNumber(f[3], td, line, "range");
    r.tag_on_robot.setZero();
    events.emplace_back(r);
    ++ranges;
  });
  loc::sortByTime(events);
  const auto gt = readGroundTruth(file("_GT.txt"), GroundTruthFormat::kTimeXyPhi);

  ensureDirectory(out_dir);
  const fs::path out(out_dir);
  writeRawlog((out / "plaza.rawlog").string(), events);
  writeFileAtomic((out / "ground_truth.tum").string(), formatTum(gt));
  writeFileAtomic((out / "anchors.csv").string(), formatAnchorsCsv(anchors));
  ManifestDraft m;
  m.comments = {"Imported by 'uwbloc import plaza' from " + fs::absolute(dir).string()};
  m.name = "plaza_" + prefix;
  m.rawlog = "plaza.rawlog";
  m.ground_truth = "ground_truth.tum";
  m.ground_truth_format = GroundTruthFormat::kTum;
  m.anchors_csv = "anchors.csv";
  m.tag_height = 0.0;
  ImportSummary summary;
  summary.manifest = writeManifest(out_dir, m);
  summary.ranges = ranges;
  summary.anchors = static_cast<long>(anchors.size());
  summary.ground_truth_rows = static_cast<long>(gt.size());
  return summary;
}

}  // namespace uwbloc::data
