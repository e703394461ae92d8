// libFuzzer target: the text readers that take a file (anchors CSV, the three ground-truth forms,
// manifests), fed one input through a scratch file.
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <string>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/manifest.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/uwbloc_fuzz_" + std::to_string(getpid()) + ".txt";
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  const std::vector<double> steps{0.0, 1.0, 2.0};
  auto guarded = [](auto&& f) {
    try {
      f();
    } catch (const uwbloc::data::InputError&) {
    }
  };
  using uwbloc::data::GroundTruthFormat;
  guarded([&] { uwbloc::data::loadAnchorsCsv(path); });
  guarded([&] { uwbloc::data::readGroundTruth(path, GroundTruthFormat::kTum); });
  guarded([&] { uwbloc::data::readGroundTruth(path, GroundTruthFormat::kTimeXyPhi); });
  guarded([&] { uwbloc::data::readGroundTruth(path, GroundTruthFormat::kStepXyPhi, steps); });
  guarded([&] { uwbloc::data::loadManifest(path, ""); });
  return 0;
}
