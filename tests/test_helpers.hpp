// Small helpers for tests that write files.
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace uwbloc::test {

/// A fresh folder under the system temp dir, named after the running test.
inline std::filesystem::path scratchDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = std::string("uwbloc_") + info->test_suite_name() + "_" + info->name();
  for (auto& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_') c = '_';
  const auto dir = std::filesystem::temp_directory_path() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline std::string writeText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
  return path.string();
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

constexpr const char* kDemoRawlog = "/usr/share/mrpt/datasets/uwb_ro-localization_demo.rawlog";

}  // namespace uwbloc::test
