// The microphone side of the virtual test cell, beside the engine's sound and the test cell's pink floor:
//
// - Self-noise: white Gaussian noise of each microphone + preamplifier, independent per channel, scaled to an
//   A-weighted level over 20 Hz - 20 kHz (IEC 61672-1). Default 20 dB(A): a 1/2" free-field measurement
//   microphone of 12.5 mV/Pa (Bruel & Kjaer Type 4191 class, about 20 dB(A) with its preamplifier; the 50 mV/Pa
//   Type 4189 class reaches 15-16 dB(A) but only 146 dB, and the thesis engine peaks above 300 Pa at 1.75 m).
// - Directivity: each microphone hears the engine's sound (combustion noise and impacts, not the floors) through
//   its own smooth response: a cascade of peaking filters at the octave centres 125 Hz .. 16 kHz (Q 1: the
//   neighbours overlap into a smooth curve) whose gains are random per microphone and band, fixed by the setup
//   seed (the installation), with a spread sigma(f) = directivity_db sqrt(f / (f + 1 kHz)) dB: about +-0.3 dB
//   at 125 Hz, +-0.7 dB at 1 kHz, +-0.9 to +-1 dB at 4-16 kHz, the growth of a source's directivity with ka and
//   of a measurement microphone's free-field deviations above a few kHz (ISO 3744 accepts +-1 dB of
//   microphone-position scatter in the 1/3-octave bands it grades as "engineering"; IEC 61094-4 tolerances
//   widen likewise with frequency). The gains are normalised so that at every band centre the energy mean of
//   the microphones' responses is exactly 1 (the array's energy average stays unbiased). Beside it the flat
//   per-microphone gain spread (mic_gain_spread_db, 0.3 dB) remains.
// - ADC: adc_bits over +-adc_range_pa, after the microphone (the card digitises the conditioned signal), clipping
//   counted. Default 24 bit over +-800 Pa (that 12.5 mV/Pa microphone into a +-10 V sound-and-vibration card:
//   152 dB peak; the virtual engine's loudest thesis condition, full load SOI 24, peaks near 310 Pa); the step,
//   1e-4 Pa, quantises 17 dB below the self-noise.
#pragma once

#include <array>
#include <complex>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace noisemon::model::engine {

inline constexpr std::size_t kDirectivityBands = 8;
inline constexpr std::array<double, kDirectivityBands> kDirectivityBandsHz{125,  250,  500,  1000,
                                                                           2000, 4000, 8000, 16000};

struct MicChainConfig {
  double self_noise_dba = 20.0;  // A-weighted, each microphone; -inf: none
  double directivity_db = 1.0;   // spread of the directivity at high frequencies (sigma, dB); 0: none
  int adc_bits = 24;             // 0: no ADC
  double adc_range_pa = 800.0;   // full scale +-

  // No self-noise, no directivity, no ADC.
  static MicChainConfig ideal() { return {-std::numeric_limits<double>::infinity(), 0.0, 0, 800.0}; }
  bool has_self_noise() const { return self_noise_dba > -std::numeric_limits<double>::infinity(); }
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

// Spread (sigma, dB) of the directivity at frequency f: directivity_db sqrt(f / (f + 1000 Hz)).
double directivity_spread_db(double directivity_db, double f_hz);

// Per-microphone band gains (dB) of the directivity filters at rate fs: normal with the spread of each band,
// fixed by setup_seed, normalised so that the energy mean over the microphones of every filter cascade's response
// at every band centre is 1. All zero for directivity_db 0.
std::vector<std::array<double, kDirectivityBands>> directivity_gains_db(std::size_t mics, double directivity_db,
                                                                        double fs_hz, std::uint64_t setup_seed);

// One microphone's directivity: the cascade of peaking biquads (RBJ cookbook, Q 1) at the band centres
// below 0.45 fs. Streaming, no allocation.
class DirectivityFilter {
 public:
  DirectivityFilter(const std::array<double, kDirectivityBands>& gains_db, double fs_hz);
  double process(double x);
  std::complex<double> response(double f_hz) const;  // of the cascade

 private:
  struct Section {
    double b0, b1, b2, a1, a2;
    double x1 = 0, x2 = 0, y1 = 0, y2 = 0;
  };
  std::array<Section, kDirectivityBands> sections_{};
  std::size_t count_ = 0;
  double fs_;
};

// rms (Pa) of white noise sampled at fs whose A-weighted level over 20 Hz - min(20 kHz, fs / 2) is level_dba.
double self_noise_rms_pa(double level_dba, double fs_hz);

}  // namespace noisemon::model::engine
