// The A-weighted mean square of each channel per 90-degree crank-angle window of a cycle (-360 ... -270, ...,
// 270 ... 360 deg): the cycle report's crank-window levels, where crank-angle-locked sound (impacts) shows in some
// windows only and stationary noise in all alike. The samples go through a time-domain A filter
// (dsp::a_weighting_sections) and a 4th-order Butterworth high-pass at 200 Hz (a window lasts 4.9 ms at 3050 rpm:
// slower content is not located in it) beside the band bank, which they leave untouched.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "dsp/iir_design.hpp"

namespace noisemon::daemon {

inline constexpr std::size_t kCrankWindows = 8;

class CrankWindows {
 public:
  CrankWindows(std::size_t channels, double fs_hz);

  // 0 ... 7 for a crank angle in [-360, 360).
  [[nodiscard]] static std::size_t window_of(double crank_deg);

  // One frame of `channels` samples that belongs to window w.
  void add(std::size_t w, const double* frame);
  // Ends the cycle: each window's mean squares are kept for mean_square() until the next close.
  void close();
  // The closed cycle's A-weighted mean square of a channel in window w; NaN when no frame fell in it.
  [[nodiscard]] double mean_square(std::size_t w, std::size_t channel) const;

 private:
  std::size_t channels_;
  std::vector<dsp::Biquad> sections_;
  std::vector<double> z0_, z1_;       // [s * channels + c]: the direct form II transposed state, section-major so that
  std::vector<double> x_;             // the loop over the channels vectorises; x_: one frame on its way through
  std::vector<double> sum_, closed_;  // [w * channels + c]
  std::array<std::size_t, kCrankWindows> frames_{}, closed_frames_{};
};

}  // namespace noisemon::daemon
