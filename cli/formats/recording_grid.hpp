// The 40 kHz grid of a recording, shared by its conversion (recording.cpp) and its log file
// (recording_log.cpp): a frame's instant, and the mean speed of a stretch of the crank channel.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "drivers/source.hpp"

namespace noisemon::cli::formats::grid {

inline constexpr double kFs = drivers::kPipelineRateHz;

// The utime of frame `index` of a recording whose frame 0 is at `epoch`.
inline std::int64_t utime_of_index(std::int64_t epoch, std::int64_t index) {
  return drivers::utime_of_frame(epoch, static_cast<double>(index));
}

// Mean speed of a stretch of the wrapped crank channel (for a recording without operating points).
inline double speed_from_crank(const std::vector<double>& crank) {
  double unwrapped = 0;
  for (std::size_t i = 1; i < crank.size(); ++i) {
    double d = crank[i] - crank[i - 1];
    if (d < -360.0) d += 720.0;
    unwrapped += d;
  }
  const double seconds = static_cast<double>(crank.size() - 1) / kFs;
  return seconds > 0 ? unwrapped / seconds / 6.0 : 0.0;
}

}  // namespace noisemon::cli::formats::grid
