// `noisemon calibrate --pressure`: the in-cylinder pressure chain's zero (offset) and gain, with the engine stopped
// and the transducer at a steady, known pressure. The zero, at ambient (a barometer's reading): [comedi.pressure]
// offset_bar so the chain reads the reference there. The gain, after a zero, with a dead-weight tester or a
// reference transducer at 5 bar or more: the chain's sensitivity scaled by what it reads above the zero against
// what was applied (and the offset rescaled so the zero holds). The values are written into the configuration
// file (that line alone, comments kept, the file replaced atomically) and appended to the calibration history.
// A charge chain has no absolute zero (its amplifier drifts and is reset): its zero is refused, its gain allowed.
#pragma once

#include <string>

#include "cli/source_capture.hpp"

namespace noisemon::cli {

struct PressureCalibration {
  std::string config_path;
  std::string history_path;  // empty: the configuration's (beside the file)
  std::string serial;        // the transducer's, for the history
  double reference_bar = 0.0;
  bool gain = false;  // false: the zero
  double seconds = 5.0;
  bool dry_run = false;
};

// Measures (the pressure on the card's timer: PressureClock::kAtRest), checks, writes; returns the exit status. Throws
// with the reason it refuses (engine turning, the reading not steady, a charge chain's zero, a gain below 5 bar or
// before a zero). make: how the source is built (empty: daemon::make_source).
int calibrate_pressure(const PressureCalibration& request, const SourceMaker& make = {});

}  // namespace noisemon::cli
