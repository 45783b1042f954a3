// An ideal N-bit analog-to-digital converter over [min, max): step (max - min) / 2^N, rounding to the nearest of the
// codes 0 .. 2^N - 1. Inputs beyond the range clip to the end codes and are counted: clipping is never silent.
// Default-constructed (or 0 bits): no converter, values pass unchanged.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>

namespace noisemon::model::engine {

class Adc {
 public:
  Adc() = default;
  Adc(int bits, double min, double max) : bits_(bits), min_(min) {
    if (bits == 0) return;
    if (bits < 4 || bits > 32) throw std::invalid_argument("ADC: bits must be 0 (none) or 4 .. 32");
    if (!(max > min)) throw std::invalid_argument("ADC: the range's top must be above its bottom");
    step_ = (max - min) / std::ldexp(1.0, bits);
    top_ = std::ldexp(1.0, bits) - 1.0;
  }
  bool active() const { return bits_ > 0; }
  double step() const { return step_; }  // 0 without a converter
  double convert(double v) {
    if (bits_ == 0) return v;
    double code = std::nearbyint((v - min_) / step_);
    if (code < 0.0) {
      code = 0.0;
      ++clipped_;
    } else if (code > top_) {
      code = top_;
      ++clipped_;
    }
    return min_ + code * step_;
  }
  void convert(double* x, std::size_t n) {
    if (bits_ == 0) return;
    for (std::size_t i = 0; i < n; ++i) x[i] = convert(x[i]);
  }
  std::uint64_t clipped() const { return clipped_; }  // samples clipped so far

 private:
  int bits_ = 0;
  double min_ = 0.0, step_ = 0.0, top_ = 0.0;
  std::uint64_t clipped_ = 0;
};

}  // namespace noisemon::model::engine
