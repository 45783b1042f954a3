// What a test needs from outside the tree (the shared reference data, root for a private network namespace,
// Chromium, python3-h5py): on a developer's machine that lacks it the test is skipped, saying what is missing; under
// CI, where the project's scripts install everything, it fails. One rule for "under CI": the variable CI set to
// anything but "", "0" or "false".
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

namespace noisemon::test {

[[nodiscard]] inline bool under_ci() {
  const char* ci = std::getenv("CI");
  if (ci == nullptr) return false;
  const std::string_view v(ci);
  return !v.empty() && v != "0" && v != "false";
}

#ifdef NOISEMON_SHARED_DIR
// The path of ../shared/data/real/NAME, or "" when it is missing (a failure under CI: the caller skips on "").
[[nodiscard]] inline std::string reference_file(const std::string& name) {
  const std::string path = std::string(NOISEMON_SHARED_DIR) + "/data/real/" + name;
  if (std::filesystem::exists(path)) return path;
  if (under_ci()) ADD_FAILURE() << path << " missing (under CI the reference data must be present)";
  return "";
}
#endif

}  // namespace noisemon::test

// Unless `present`: skips the test, or fails it under CI; `what` says what is missing.
#define NOISEMON_REQUIRE(present, what)                                  \
  do {                                                                   \
    if (!(present)) {                                                    \
      if (::noisemon::test::under_ci()) FAIL() << "missing: " << (what); \
      GTEST_SKIP() << "missing: " << (what);                             \
    }                                                                    \
  } while (0)
