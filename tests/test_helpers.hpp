// Small helpers for tests that write files.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "uwbloc/dataset/data_dir.hpp"

namespace uwbloc::test {

/// A fresh folder under the system temp dir, named after the running test and the process (two
/// suites running at once on one machine must not share it), removed when the process ends.
inline std::filesystem::path scratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string("uwbloc_") + info->test_suite_name() + "_" + info->name();
  for (auto& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') c = '_';
  name += "_" + std::to_string(::getpid());
  const auto dir = std::filesystem::temp_directory_path() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  struct RemovedAtExit {
    std::vector<std::filesystem::path> dirs;
    ~RemovedAtExit() {
      std::error_code ignored;
      for (const auto& d : dirs) std::filesystem::remove_all(d, ignored);
    }
  };
  static RemovedAtExit made;
  made.dirs.push_back(dir);
  return dir;
}

inline std::string writeText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path.string();
}

inline std::string readText(const std::filesystem::path& path) {
  std::ostringstream text;
  text << std::ifstream(path).rdbuf();
  return text.str();
}

/// Runs `body`, expecting an exception whose message contains every one of `parts`.
template <class Exception, class Body>
void expectErrorMentions(Body body, std::initializer_list<std::string> parts) {
  try {
    body();
    ADD_FAILURE() << "no exception thrown";
  } catch (const Exception& e) {
    const std::string what = e.what();
    for (const auto& p : parts) EXPECT_NE(what.find(p), std::string::npos) << what;
  }
}

/// True when running in CI (CI=true), where a missing shared dataset is a failure.
inline bool inCi() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

/// A path in the shared data directory, found at run time: $UWBLOC_DATA_DIR, else
/// ../shared/datasets beside the project (see data::resolveDataDir).
inline std::filesystem::path sharedData(const std::string& relative) {
  return std::filesystem::path(data::resolveDataDir()) / relative;
}

constexpr const char* kDemoRawlog = "/usr/share/mrpt/datasets/uwb_ro-localization_demo.rawlog";

}  // namespace uwbloc::test

/// Stops the test when a shared dataset is missing: skipped (with the file named) outside CI,
/// failed in CI, so that a missing dataset never turns CI green.
#define UWBLOC_REQUIRE_SHARED_DATA(path)                                                    \
  do {                                                                                      \
    if (!std::filesystem::exists(path)) {                                                   \
      if (::uwbloc::test::inCi())                                                           \
        FAIL() << "missing shared dataset " << (path) << " (CI=true: the datasets must be " \
               << "at ../shared/datasets or $UWBLOC_DATA_DIR)";                             \
      GTEST_SKIP() << "missing shared dataset " << (path)                                   \
                   << " (set UWBLOC_DATA_DIR to the shared datasets folder)";               \
    }                                                                                       \
  } while (0)
