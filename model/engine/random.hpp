// Seeded random numbers for the virtual engine: reproducible from a seed, and independent between streams so
// that switching one effect on never changes the random realisation of another.
//
// Two kinds:
//  - counter-based (hash of seed, stream and index): the value for sample i does not depend on where a
//    computation started or how it was chunked (encoder samples, per-cycle impacts);
//  - sequential (xoshiro256** + Box-Muller): cheap per-sample Gaussian noise for long streams that are always
//    generated from the same start.
#pragma once

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <numbers>

namespace noisemon::model::engine::rnd {

inline std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// A well-mixed 64-bit key for (seed, stream, index).
inline std::uint64_t key(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  std::uint64_t s = seed;
  std::uint64_t h = splitmix64(s) ^ (stream * 0xD1B54A32D192ED03ULL);
  h = splitmix64(h) ^ index;
  return splitmix64(h);
}

// Uniform in (0, 1], from a 64-bit value.
inline double unit(std::uint64_t bits) { return (static_cast<double>(bits >> 11) + 1.0) * 0x1.0p-53; }

// Counter-based standard normal value for (seed, stream, index).
inline double normal_at(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  std::uint64_t s = key(seed, stream, index);
  const double u1 = unit(splitmix64(s));
  const double u2 = unit(splitmix64(s));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

// Sequential standard normal generator.
class Normal {
 public:
  explicit Normal(std::uint64_t seed) {
    for (auto& v : s_) v = splitmix64(seed);
  }
  double next() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = unit(next_u64());
    const double u2 = unit(next_u64());
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * std::numbers::pi * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  std::uint64_t next_u64() {  // xoshiro256**
    const std::uint64_t result = std::rotl(s_[1] * 5, 7) * 9;
    const std::uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = std::rotl(s_[3], 45);
    return result;
  }
  std::array<std::uint64_t, 4> s_{};
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace noisemon::model::engine::rnd
