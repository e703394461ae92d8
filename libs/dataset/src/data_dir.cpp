#include "uwbloc/dataset/data_dir.hpp"

#include <cstdlib>
#include <filesystem>
#include <vector>

namespace fs = std::filesystem;

namespace uwbloc::data {

namespace {

// The folders that hold the project's own datasets/ (the MRPT demo's manifest, the scenarios):
// found at run time from the running program's location (the build tree's apps/uwbloc/uwbloc,
// a test in build/tests, or an installed bin/uwbloc with share/uwbloc beside it) and from the
// working directory. No path is compiled in.
std::vector<fs::path> bundledRoots() {
  std::vector<fs::path> roots;
  std::error_code ec;
  auto search = [&](fs::path p) {
    for (int depth = 0; depth < 6 && !p.empty(); ++depth, p = p.parent_path()) {
      if (fs::is_regular_file(p / "datasets" / "mrpt_uwb_demo.ini", ec)) roots.push_back(p);
      if (fs::is_directory(p / "share" / "uwbloc" / "datasets", ec))
        roots.push_back(p / "share" / "uwbloc");
      if (p == p.parent_path()) break;
    }
  };
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) search(exe.parent_path());
  search(fs::current_path(ec));
  return roots;
}

}  // namespace

std::string resolveDataDir(const std::string& flag) {
  if (!flag.empty()) return flag;
  if (const char* env = std::getenv("UWBLOC_DATA_DIR"); env && *env) return env;
  std::vector<fs::path> candidates;
  for (const auto& root : bundledRoots()) candidates.push_back(root / ".." / "shared" / "datasets");
  std::error_code ec;
  candidates.push_back(fs::current_path(ec) / ".." / "shared" / "datasets");
  for (const auto& candidate : candidates)
    if (fs::is_directory(candidate, ec)) return fs::canonical(candidate, ec).string();
  return "";
}

std::string projectDatasetsDir() {
  const auto roots = bundledRoots();
  return roots.empty() ? "" : (roots.front() / "datasets").string();
}

std::string resolveInputPath(const std::string& path, const std::string& data_dir) {
  std::error_code ec;
  if (path.empty() || fs::exists(path, ec)) return path;
  if (!data_dir.empty() && fs::exists(fs::path(data_dir) / path, ec))
    return (fs::path(data_dir) / path).string();
  for (const auto& root : bundledRoots())
    for (const char* folder : {"datasets", "datasets/scenarios"}) {
      const fs::path bundled = root / folder / path;
      if (fs::exists(bundled, ec)) return bundled.string();
    }
  return path;
}

}  // namespace uwbloc::data
