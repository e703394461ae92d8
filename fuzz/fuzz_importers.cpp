// libFuzzer target: the dataset importers. The first byte picks the importer; the rest is split
// at lines "@@" into that importer's input files:
//   0 CARMEN: the log;
//   1 Hanyang run: A3.csv, A5.csv, trajectory.csv;
//   2 Plaza: P_DR.txt, P_TD.txt, P_TL.txt, P_GT.txt;
//   3 Hanyang static file (the two-way-ranging timestamps);
//   4 Plaza with its reference and beacons in a .mat (read by libmatio);
//   5 CSV: ranges, anchors, odometry, imu, reference, scans;
//   6 libRSF: X_Input.txt, X_GT.txt;
//   7 LIAS: its README, a dynamic UWB file and its motion capture; then, when given, the static
//     README and a static UWB file, imported beside that dynamic run (which gives its frame).
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "uwbloc/dataset/carmen_import.hpp"
#include "uwbloc/dataset/csv_import.hpp"
#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/hanyang_import.hpp"
#include "uwbloc/dataset/lias_import.hpp"
#include "uwbloc/dataset/librsf_import.hpp"
#include "uwbloc/dataset/plaza_import.hpp"

namespace fs = std::filesystem;

namespace {

std::vector<std::string> splitParts(const std::string& text) {
  std::vector<std::string> parts(1);
  size_t start = 0;
  for (;;) {
    const size_t at = text.find("\n@@\n", start);
    parts.back() += text.substr(start, at == std::string::npos ? std::string::npos : at - start);
    if (at == std::string::npos) return parts;
    parts.emplace_back();
    start = at + 4;
  }
}

void writeParts(const fs::path& dir, const std::vector<std::string>& names,
                const std::vector<std::string>& parts) {
  for (size_t i = 0; i < names.size() && i < parts.size(); ++i)
    if (!names[i].empty()) std::ofstream(dir / names[i], std::ios::binary) << parts[i];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  static const fs::path root =
      fs::temp_directory_path() / ("uwbloc_fuzz_import_" + std::to_string(getpid()));
  const fs::path in = root / "in", out = root / "out";
  fs::remove_all(root);
  fs::create_directories(in);
  const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
  const auto parts = splitParts(text);
  try {
    switch (data[0] % 8) {
      case 0:
        writeParts(in, {"intel.log"}, parts);
        uwbloc::data::importCarmen((in / "intel.log").string(), out.string());
        break;
      case 1:
        writeParts(in, {"A3.csv", "A5.csv", "trajectory.csv"}, parts);
        uwbloc::data::importHanyang(in.string(), out.string());
        break;
      case 2:
        writeParts(in, {"P_DR.txt", "P_TD.txt", "P_TL.txt", "P_GT.txt"}, parts);
        uwbloc::data::importPlaza(in.string(), out.string());
        break;
      case 3:
        writeParts(in, {"5m.csv"}, parts);
        uwbloc::data::readHanyangStatic((in / "5m.csv").string());
        break;
      case 4:
        writeParts(in, {"P_DR.txt", "P_TD.txt", "P.mat"}, parts);
        uwbloc::data::importPlaza(in.string(), out.string());
        break;
      case 5: {
        writeParts(in, {"r.csv", "a.csv", "o.csv", "i.csv", "g.csv", "s.csv"}, parts);
        uwbloc::data::CsvImportRequest r;
        r.ranges = (in / "r.csv").string();
        r.anchors = (in / "a.csv").string();
        if (parts.size() > 2) r.odometry = (in / "o.csv").string();
        if (parts.size() > 3) r.imu = (in / "i.csv").string();
        if (parts.size() > 4) r.reference = (in / "g.csv").string();
        if (parts.size() > 5) r.scans = (in / "s.csv").string();
        uwbloc::data::importCsv(r, out.string());
        break;
      }
      case 6:
        writeParts(in, {"X_Input.txt", "X_GT.txt"}, parts);
        uwbloc::data::importLibrsf((in / "X_Input.txt").string(), out.string());
        break;
      default: {
        fs::create_directories(in / "Planar_Dataset" / "Dynamic");
        fs::create_directories(in / "Dynamic");
        writeParts(in,
                   {"Planar_Dataset/Dynamic/README.md", "Dynamic/UWB_dynamic_exp_f.csv",
                    "Dynamic/motion_capture_dynamic_exp_f.csv"},
                   parts);
        if (parts.size() > 4) {
          fs::create_directories(in / "Planar_Dataset" / "Static");
          fs::create_directories(in / "Static");
          writeParts(in,
                     {"", "", "", "Planar_Dataset/Static/README.md",
                      "Static/UWB_static_exp_8_14_pos1_deg_0.csv"},
                     parts);
          try {
            uwbloc::data::importLias(
                (in / "Static" / "UWB_static_exp_8_14_pos1_deg_0.csv").string(),
                (out / "static").string());
          } catch (const uwbloc::data::InputError&) {
          }
        }
        uwbloc::data::importLias((in / "Dynamic" / "UWB_dynamic_exp_f.csv").string(), out.string());
        break;
      }
    }
  } catch (const uwbloc::data::InputError&) {
  }
  return 0;
}
