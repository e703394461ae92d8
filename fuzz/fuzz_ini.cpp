// libFuzzer target: the INI reader (manifests, scenarios, --config files).
#include <cstdint>
#include <string>

#include "uwbloc/dataset/errors.hpp"
#include "uwbloc/dataset/ini_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const auto ini = uwbloc::data::IniFile::fromString(text, "fuzz.ini");
    for (const auto& section : ini.sections())
      for (const auto& key : ini.keys(section)) {
        ini.getString(section, key, "");
        try {
          ini.getDouble(section, key);
        } catch (const uwbloc::data::InputError&) {
        }
      }
  } catch (const uwbloc::data::InputError&) {
  }
  return 0;
}
