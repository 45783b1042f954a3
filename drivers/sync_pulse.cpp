#include "drivers/sync_pulse.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace noisemon::drivers {

SyncPulseDetector::SyncPulseDetector(double min_swing, double level_scans) : min_swing_(min_swing) {
  if (!(min_swing > 0.0) || !(level_scans >= 1.0))
    throw std::invalid_argument("SyncPulseDetector: the swing and the level span must be positive");
  decay_ = 1.0 / level_scans;
}

void SyncPulseDetector::reset() {
  started_ = false;
  armed_ = false;
}

bool SyncPulseDetector::add(double value, std::int64_t q, double* edge_q) {
  if (!std::isfinite(value)) {  // a lost sample: start the levels over
    started_ = false;
    return false;
  }
  if (!started_) {
    low_ = high_ = previous_ = value;
    started_ = true;
    armed_ = false;
    return false;
  }
  // The levels follow the extremes at once and relax towards each other slowly (a peak/valley follower).
  const double relax = (high_ - low_) * decay_;
  high_ = std::max(value, high_ - relax);
  low_ = std::min(value, low_ + relax);
  const double swing = high_ - low_;
  bool found = false;
  if (swing >= min_swing_) {
    const double threshold = low_ + 0.5 * swing;
    if (value <= low_ + 0.3 * swing) armed_ = true;
    if (armed_ && value >= threshold && previous_ < threshold) {
      *edge_q = static_cast<double>(q - 1) + (threshold - previous_) / (value - previous_);
      armed_ = false;
      found = true;
    }
  }
  previous_ = value;
  return found;
}

}  // namespace noisemon::drivers
