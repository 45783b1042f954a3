// Latencies of the cycles reported in the last second, for the status message's percentiles. Used by the
// publishing thread only; its storage is reserved once, so adding never allocates.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace noisemon::daemon {

class LatencyWindow {
 public:
  // Beyond `capacity` values in one window (a replay running far faster than real time) the later ones are
  // left out of the percentiles but still count for the maximum.
  explicit LatencyWindow(std::size_t capacity = 16384) { values_.reserve(capacity); }

  void add(double ms) {
    if (values_.size() < values_.capacity()) values_.push_back(ms);
    max_ = std::max(max_, ms);
  }
  // The q-quantile (0..1) of the window, nearest rank; 0 when it is empty. Reorders the values.
  double quantile(double q) {
    if (values_.empty()) return 0.0;
    const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(values_.size())));
    const auto at = values_.begin() + static_cast<std::ptrdiff_t>(std::clamp<std::size_t>(rank, 1, values_.size()) - 1);
    std::nth_element(values_.begin(), at, values_.end());
    return *at;
  }
  double max() const { return max_; }
  void clear() {
    values_.clear();
    max_ = 0.0;
  }

 private:
  std::vector<double> values_;
  double max_ = 0.0;
};

}  // namespace noisemon::daemon
