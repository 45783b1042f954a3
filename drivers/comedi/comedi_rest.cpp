#include "drivers/comedi/comedi_rest.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace noisemon::drivers::comedi {

void check_rest_scan_rate(double hz) {
  if (!(hz >= kMinRestScanRateHz && hz <= kMaxRestScanRateHz) || hz != std::round(hz))
    throw std::invalid_argument(
        "comedi.pressure.rest_scan_rate_hz: " + std::to_string(hz) +
        " Hz: the pressure's scan rate on the card's timer with the engine at rest must be a whole number of Hz from " +
        std::to_string(static_cast<long>(kMinRestScanRateHz)) + " to " +
        std::to_string(static_cast<long>(kMaxRestScanRateHz)) + " (e.g. 10000 or 40000)");
}

ComediAcquisitionConfig rest_pressure_acquisition(const ComediAcquisitionConfig& edge_clocked,
                                                  double rest_scan_rate_hz) {
  check_rest_scan_rate(rest_scan_rate_hz);
  ComediAcquisitionConfig p = edge_clocked;
  p.clock = ScanClock::kTimed;
  p.scan_rate_hz = rest_scan_rate_hz;
  p.start_trigger = -1;
  p.channels.resize(1);  // the pressure; the cam has nothing to say at rest
  return p;
}

RestSpeedMeter::RestSpeedMeter(double edges_per_rev, std::chrono::milliseconds window)
    : edges_per_rev_(edges_per_rev), window_(window), since_(std::chrono::steady_clock::now()) {}

void RestSpeedMeter::after_pass(OperatingPointRing* ring) {
  const auto now = std::chrono::steady_clock::now();
  if (now - since_ < window_) return;
  const double seconds = std::chrono::duration<double>(now - since_).count();
  OperatingPoint op;
  op.utime = wall_utime();
  op.speed_rpm = 60.0 * static_cast<double>(window_edges_) / edges_per_rev_ / seconds;
  op.load_nm = op.soi_deg_btdc = op.rail_pressure_bar = std::numeric_limits<double>::quiet_NaN();
  if (ring) (void)ring->push(op);  // a full ring (nobody reading) loses the speed, not the pressure
  since_ = now;
  window_edges_ = 0;
}

}  // namespace noisemon::drivers::comedi
