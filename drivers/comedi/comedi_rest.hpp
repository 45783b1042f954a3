// The engine at rest on the comedi card (ComediSourceConfig::at_rest, for `noisemon calibrate --pressure` and the
// pressure row of `noisemon check`): no encoder edges come to clock the pressure, so its channel is scanned on the
// card's timer instead, converted exactly as the edge-clocked scan converts it (sensitivity, offset_bar); the
// encoder's counter still runs on its edges, and any edge that comes is counted into a speed, so an engine that
// turns while it should be at rest shows as one.
#pragma once

#include <chrono>
#include <cstdint>

#include "drivers/comedi/comedi_device.hpp"
#include "drivers/source.hpp"

namespace noisemon::drivers::comedi {

// The range of [comedi.pressure] rest_scan_rate_hz; the rate must be a whole number of Hz (it is resampled to 40 kHz).
inline constexpr double kMinRestScanRateHz = 1000.0;
inline constexpr double kMaxRestScanRateHz = 1e6;

// Throws std::invalid_argument naming comedi.pressure.rest_scan_rate_hz unless hz is a whole number of Hz in range.
void check_rest_scan_rate(double hz);

// The edge-clocked pressure acquisition turned onto the card's timer at rest_scan_rate_hz: the pressure channel
// alone (a cam channel is left out), its conversion unchanged.
ComediAcquisitionConfig rest_pressure_acquisition(const ComediAcquisitionConfig& edge_clocked,
                                                  double rest_scan_rate_hz);

// The speed of the crank from the encoder edges counted over windows of host time: with the engine at rest, 0.
class RestSpeedMeter {
 public:
  explicit RestSpeedMeter(double edges_per_rev, std::chrono::milliseconds window = std::chrono::milliseconds(100));
  void add_edge() {
    ++edges_;
    ++window_edges_;
  }
  // After a read pass: once a window has passed since the last, its speed as an operating point (speed only: load,
  // injection and rail pressure NaN) written to ring (nullptr: not written).
  void after_pass(OperatingPointRing* ring);
  std::uint64_t edges() const { return edges_; }

 private:
  double edges_per_rev_;
  std::chrono::steady_clock::duration window_;
  std::chrono::steady_clock::time_point since_;
  std::uint64_t edges_ = 0, window_edges_ = 0;
};

}  // namespace noisemon::drivers::comedi
