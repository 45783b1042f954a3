// Shared by the libFuzzer targets: a per-process scratch file the fuzz bytes are written to (the readers under
// test take paths), and the check that a rejection is a clear error rather than a crash.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <string_view>

namespace noisemon::fuzz {

// A directory of this process's own under $TMPDIR (or /tmp), removed at exit.
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    const char* tmp = std::getenv("TMPDIR");
    std::filesystem::path d =
        std::filesystem::path(tmp && *tmp ? tmp : "/tmp") / ("noisemon-fuzz-" + std::to_string(getpid()));
    std::filesystem::create_directories(d);
    static const std::filesystem::path remove_me = d;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(remove_me, ec);
    });
    return d;
  }();
  return dir;
}

inline void write_file(const std::filesystem::path& path, const std::uint8_t* data, std::size_t size) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || (size > 0 && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) {
    std::fprintf(stderr, "fuzz harness: cannot write %s\n", path.c_str());
    std::abort();
  }
}

inline void write_file(const std::filesystem::path& path, std::string_view text) {
  write_file(path, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

// A rejection must say what it rejected: a message that names `what` (the file, or "line N").
inline void require_names(std::string_view message, std::string_view what) {
  if (message.find(what) == std::string_view::npos) {
    std::fprintf(stderr, "fuzz: error message does not name '%.*s': %.*s\n", static_cast<int>(what.size()), what.data(),
                 static_cast<int>(message.size()), message.data());
    std::abort();
  }
}

// An invariant of an accepted input that does not hold.
[[noreturn]] inline void fail(const char* what) {
  std::fprintf(stderr, "fuzz: invariant violated: %s\n", what);
  std::abort();
}

}  // namespace noisemon::fuzz
