#include "uwbloc/dataset/data_dir.hpp"

#include <cstdlib>
#include <filesystem>

namespace fs = std::filesystem;

namespace uwbloc::data {

std::string resolveDataDir(const std::string& flag) {
  if (!flag.empty()) return flag;
  if (const char* env = std::getenv("UWBLOC_DATA_DIR"); env && *env) return env;
  for (const fs::path& candidate : {fs::path(UWBLOC_SOURCE_DIR) / ".." / "shared" / "datasets",
                                    fs::current_path() / ".." / "shared" / "datasets"}) {
    std::error_code ec;
    if (fs::is_directory(candidate, ec)) return fs::canonical(candidate, ec).string();
  }
  return "";
}

std::string resolveInputPath(const std::string& path, const std::string& data_dir) {
  std::error_code ec;
  if (path.empty() || fs::exists(path, ec)) return path;
  if (!data_dir.empty() && fs::exists(fs::path(data_dir) / path, ec))
    return (fs::path(data_dir) / path).string();
  for (const char* folder : {"datasets", "datasets/scenarios"}) {
    const fs::path bundled = fs::path(UWBLOC_SOURCE_DIR) / folder / path;
    if (fs::exists(bundled, ec)) return bundled.string();
  }
  return path;
}

}  // namespace uwbloc::data
