// A few seconds of the configured sources, as the daemon would start them, held in memory: for the commands that
// look at the measurement chain itself (`noisemon calibrate`, `noisemon check`) rather than at engine cycles.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/sources.hpp"
#include "drivers/source.hpp"

namespace noisemon::cli {

struct CapturedStreams {
  drivers::StreamInfo info;
  std::vector<std::vector<double>> mics;  // one unbroken stretch per microphone, Pa at 40 kHz (the latest after a gap)
  std::vector<double> pressure_pa, crank_deg;  // the 40 kHz pressure stream, as delivered
  std::size_t mic_gaps = 0;                    // gaps in the microphone stream (overruns)
  std::size_t operating_points = 0;
  double last_speed_rpm = 0.0;
  double max_speed_rpm = 0.0;  // the fastest operating point while listening (the engine turned at some time)
  std::vector<drivers::DriverCounter> counters;
  std::vector<drivers::DriverThreadStatus> threads;
};

// How the source is built: daemon::make_source; the tests give one of their own (the comedi source on the pipes of
// tests/drivers/comedi_fake_card.hpp).
using SourceMaker = std::function<std::unique_ptr<drivers::Source>(const daemon::Config&, daemon::PressureClock)>;

// Starts the configured source, drops its first `settle_s`, then keeps `seconds` of unbroken microphone stream (and
// whatever pressure came meanwhile); stops it. clock kAtRest: the pressure on the card's timer (the engine stopped;
// daemon/sources.hpp). Throws naming the device when the source cannot start, a driver thread failed, or the stream
// did not come within a generous deadline.
CapturedStreams capture_streams(const daemon::Config& config, double seconds, double settle_s = 0.5,
                                daemon::PressureClock clock = daemon::PressureClock::kEncoder,
                                const SourceMaker& make = {});

// The engine cycles the crank angle began while listening (the engine turns when there are any).
std::size_t engine_cycles_seen(const CapturedStreams& streams);

}  // namespace noisemon::cli
