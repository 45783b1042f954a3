// A whole file as a string, for comparing what programs wrote and for showing their logs when a test fails.
#pragma once

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace noisemon::test {

// The file's bytes; empty when it cannot be read (a log the program never wrote).
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace noisemon::test
