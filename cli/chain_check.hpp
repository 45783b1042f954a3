// What `noisemon check` finds in the measurement chain: each microphone's level and floor (dead, clipped,
// implausible against the others), the pressure transducer's offset with the engine stopped (on a card whose encoder
// clocks the pressure, listened to again on the card's timer), the encoder when it turns, CAN's operating points, the
// drivers' error counters and the acoustic front-end's clock. One row each; the command prints and publishes them.
#pragma once

#include <string>
#include <vector>

#include "cli/source_capture.hpp"
#include "daemon/config.hpp"

namespace noisemon::cli {

struct CheckRow {
  std::string item, value, verdict;
  bool failed = false;
};

// Listens to the configured source for `seconds` (and 1 s more at rest when no pressure came with the engine
// stopped). make: how the source is built (empty: daemon::make_source). Throws as capture_streams does.
std::vector<CheckRow> check_measurement_chain(const daemon::Config& config, double seconds,
                                              const SourceMaker& make = {});

}  // namespace noisemon::cli
