// Big-endian integers as LCM writes them, in its messages and its log files' event headers.
#pragma once

#include <cstdint>

namespace noisemon::drivers::formats {

[[nodiscard]] inline std::uint64_t read_be64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}
[[nodiscard]] inline std::int32_t read_be32(const std::uint8_t* p) {
  return static_cast<std::int32_t>((std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) |
                                   (std::uint32_t{p[2]} << 8) | p[3]);
}
[[nodiscard]] inline std::int16_t read_be16(const std::uint8_t* p) {
  return static_cast<std::int16_t>((p[0] << 8) | p[1]);
}

}  // namespace noisemon::drivers::formats
