// A sound calibrator's tone as a microphone hears it: its frequency, its level and how steady it is, and how much of
// the signal it is (a calibrator not seated on the microphone leaves mostly the room). For `noisemon calibrate`.
#pragma once

#include <cstddef>
#include <span>

namespace noisemon::dsp {

struct ToneMeasurement {
  double frequency_hz = 0.0;    // the tone's frequency, from its phase advance
  double rms = 0.0;             // the tone's rms (the unit of the samples)
  double total_rms = 0.0;       // the whole signal's rms
  double fluctuation_db = 0.0;  // the highest minus the lowest level of its half-second blocks
  std::size_t half_seconds = 0;
};

// The tone nearest `nominal_hz` in `samples` at `rate_hz`, if it lies within +-40 Hz of it (10 ms blocks, whose
// phase then advances by less than half a turn): demodulated at the nominal frequency in 10 ms blocks, its
// frequency from the blocks' phase slope, then demodulated again at that frequency for its level. Needs at least
// one second of samples (std::invalid_argument).
ToneMeasurement measure_tone(std::span<const double> samples, double rate_hz, double nominal_hz);

}  // namespace noisemon::dsp
