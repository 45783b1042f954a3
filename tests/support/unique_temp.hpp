// Temporary paths no other process uses: <gtest TempDir>/noisemon-<pid>/<Suite.Test>/<name>. Test executables
// of several build directories (and ctest -j) run at once; with fixed names under /tmp one truncated a log the
// other had mapped (SIGBUS in the log reader) or read the other's output.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace noisemon::test {

// This process's scratch directory, removed at exit by the process that made it (not by forked children);
// kept when NOISEMON_KEEP_TEMP is set, to look at a failure's files.
inline const std::filesystem::path& process_temp_dir() {
  static const pid_t owner = ::getpid();
  static const std::filesystem::path dir = [] {
    const std::filesystem::path d = std::filesystem::path(::testing::TempDir()) / ("noisemon-" + std::to_string(owner));
    std::filesystem::create_directories(d);
    return d;
  }();
  static const struct Remover {
    ~Remover() {
      if (::getpid() != owner || std::getenv("NOISEMON_KEEP_TEMP")) return;
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } remover;
  return dir;
}

// The running test's own directory (the running suite's in SetUpTestSuite), created on demand.
inline std::string unique_temp_dir();

// `name` inside a directory of the running test (of the running suite in SetUpTestSuite), created on demand.
inline std::filesystem::path unique_temp(const std::string& name) {
  const auto* unit = ::testing::UnitTest::GetInstance();
  std::string scope = "global";
  if (const auto* test = unit->current_test_info())
    scope = std::string(test->test_suite_name()) + "." + test->name();
  else if (const auto* suite = unit->current_test_suite())
    scope = suite->name();
  std::replace(scope.begin(), scope.end(), '/', '_');  // parameterised tests: Suite/Test/0
  const std::filesystem::path dir = process_temp_dir() / scope;
  std::filesystem::create_directories(dir);
  return dir / name;
}

inline std::string unique_temp_dir() { return unique_temp("").parent_path().string(); }

}  // namespace noisemon::test
