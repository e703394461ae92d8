// libFuzzer target: the rawlog reader (MRPT's deserialiser behind uwbloc's pre-checks), fed the
// uncompressed stream through a scratch file.
#include <unistd.h>

#include <cstdint>
#include <fstream>
#include <string>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/rawlog.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/uwbloc_fuzz_" + std::to_string(getpid()) + ".rawlog";
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  try {
    uwbloc::data::readRawlog(path);
  } catch (const uwbloc::data::InputError&) {
  }
  return 0;
}
