// The rising edges of a once-per-revolution pulse (the encoder's index, a tacho) sampled by a converter beside its
// microphones: each edge's position in scans, interpolated between the two scans around the threshold. The
// threshold sits half-way between the pulse train's low and high levels, followed as they drift (an AC-coupled
// input's baseline); a hysteresis of a fifth of the swing ignores the ringing of the converter's anti-alias filter
// after an edge. The same filter delays the microphones and the pulse alike, so its delay cancels.
#pragma once

#include <cstdint>

namespace noisemon::drivers {

class SyncPulseDetector {
 public:
  // min_swing: the smallest high-low difference taken for a pulse train (in the channel's units; below it, a
  // disconnected input's noise, no edge is reported). level_scans: how many scans the levels are followed over.
  SyncPulseDetector(double min_swing, double level_scans);

  // Scan `q` of the channel; true with *edge_q set when a rising edge crossed the threshold since the last scan.
  bool add(double value, std::int64_t q, double* edge_q);
  void reset();
  [[nodiscard]] double swing() const { return high_ - low_; }

 private:
  double min_swing_;
  double decay_;  // per scan, of the levels towards each other
  double low_ = 0.0, high_ = 0.0, previous_ = 0.0;
  bool started_ = false, armed_ = false;
};

}  // namespace noisemon::drivers
