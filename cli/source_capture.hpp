// A few seconds of the configured sources, as the daemon would start them, held in memory: for the commands that
// look at the measurement chain itself (`noisemon calibrate`, `noisemon check`) rather than at engine cycles.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "drivers/source.hpp"

namespace noisemon::cli {

struct CapturedStreams {
  drivers::StreamInfo info;
  std::vector<std::vector<double>> mics;  // one unbroken stretch per microphone, Pa at 40 kHz (the latest after a gap)
  std::vector<double> pressure_pa, crank_deg;  // the 40 kHz pressure stream, as delivered
  std::size_t mic_gaps = 0;                    // gaps in the microphone stream (overruns)
  std::size_t operating_points = 0;
  double last_speed_rpm = 0.0;
  std::vector<drivers::DriverCounter> counters;
  std::vector<drivers::DriverThreadStatus> threads;
};

// Starts the configured source, drops its first `settle_s`, then keeps `seconds` of unbroken microphone stream (and
// whatever pressure came meanwhile); stops it. Throws naming the device when the source cannot start, a driver thread
// failed, or the stream did not come within a generous deadline.
CapturedStreams capture_streams(const daemon::Config& config, double seconds, double settle_s = 0.5);

// The engine cycles the crank angle began while listening (the engine turns when there are any).
std::size_t engine_cycles_seen(const CapturedStreams& streams);

}  // namespace noisemon::cli
