// libFuzzer target: the text readers that take a file (anchors CSV, the three ground-truth forms,
// manifests, the labelled-range files and NLOS model files), fed one input through a scratch
// file.
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <fstream>
#include <memory>
#include <string>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ground_truth.hpp"
#include "uwbloc/dataset/manifest.hpp"
#include "uwbloc/nlos/model.hpp"

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
  try {
    uwbloc::nlos::readLabelledRanges(path);
  } catch (const uwbloc::nlos::DataError&) {
  }
  try {
    // A model that loads must judge any range without a NaN.
    const auto model = uwbloc::nlos::Model::fromJson(
        std::string(reinterpret_cast<const char*>(data), size), "fuzz");
    uwbloc::nlos::Sample s;
    s.range = 5.0, s.rx_power_dbm = -80.0, s.fp_power_dbm = -84.0;
    if (model.centred) {  // a centred model judges ranges that carry their place's medians
      auto centre = std::make_shared<uwbloc::nlos::EnvironmentCentre>();
      centre->set = model.set;
      centre->median.fill(1.0);
      s.centre = centre;
    }
    const auto j = model.judge(s);
    if (!std::isfinite(j.p_nlos) || !std::isfinite(j.error) || !std::isfinite(j.error_sigma))
      __builtin_trap();
  } catch (const uwbloc::nlos::DataError&) {
  }
  return 0;
}
