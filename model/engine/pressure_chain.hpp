// The cylinder-pressure measurement chain of the virtual test cell: transducer, charge amplifier and ADC between
// the true pressure and the MEASURED one (docs/sources-and-formats.md, "The simulated engine"). The engine and the
// microphones hear the true pressure; only what the chain delivers carries its floor.
//
//   measured = ADC( (1 + gain_error) true + offset + white floor + 1/f (flicker) part + transducer_noise effect )
//
// - Gain error and offset: a transducer whose sensitivity is not the one its conversion assumes, and whose zero
//   is off (what `noisemon calibrate --pressure` finds and corrects). Default none.
// - White floor: Gaussian, noise_bar rms per encoder sample (over the encoder bandwidth). Default 0.02 bar: a
//   good piezoelectric chain (e.g. a Kistler 6052C / AVL GH13P-class transducer behind a charge amplifier, into a
//   16-bit card) resolves a few hundredths of a bar; the real Yanmar records in data/real carry about 0.2 bar
//   (median absolute second difference in the early compression stroke), a worn or noisy chain.
// - Flicker: 1/f noise of the charge amplifier (Voss-McCartney: kFlickerRows octave rows, row k a Gaussian held
//   for 2^k samples with a seeded offset, equal variance per row), flicker_bar rms per encoder sample over the
//   rows' band (fs / 2^kFlickerRows .. fs / 2). Default off: a charge amplifier's drift is mostly removed by
//   pegging and its 1/f corner (~10 Hz - 1 kHz) sits far below the bands the noise monitor scores.
// - ADC: adc_bits over [adc_min_bar, adc_max_bar): default 16 bit over 0 .. 250 bar (the measuring range of those
//   transducers; step 3.8 mbar, quantisation 1.1 mbar rms); beyond the range the samples clip to the end codes
//   and are counted (PressureChain::clipped_samples()).
// - transducer_noise (model/engine/effects.hpp): more floor than configured, added before the ADC.
//
// Every noise is counter-based on the global encoder sample index (model/engine/random.hpp): the measured value of
// sample i depends only on (seed, i), never on how the stream was chunked.
#pragma once

#include <cstddef>
#include <cstdint>

#include "model/engine/adc.hpp"
#include "model/engine/effects.hpp"

namespace noisemon::model::engine {

inline constexpr int kFlickerRows = 16;

struct PressureChainConfig {
  double noise_bar = 0.02;     // white floor, rms per encoder sample; 0: none
  double flicker_bar = 0.0;    // 1/f part, rms per encoder sample; 0: none
  int adc_bits = 16;           // 0: no ADC (no quantisation, no clipping)
  double adc_min_bar = 0.0;    // absolute pressure at code 0
  double adc_max_bar = 250.0;  // top of the range (exclusive)
  double offset_bar = 0.0;     // zero error: what the chain reads above the true pressure
  double gain_error = 0.0;     // sensitivity error, a fraction: +0.04 reads 4 % high

  // No floor, no flicker, no ADC, no zero or gain error: the measured pressure is the true pressure.
  static PressureChainConfig ideal() { return {0.0, 0.0, 0, 0.0, 250.0, 0.0, 0.0}; }
  bool is_ideal() const {
    return noise_bar == 0.0 && flicker_bar == 0.0 && adc_bits == 0 && offset_bar == 0.0 && gain_error == 0.0;
  }
  double adc_step_bar() const;  // 0 without an ADC
  // The chain's broadband (white) floor, bar rms per encoder sample: the white floor and the quantisation
  // (step / sqrt 12) in quadrature (the flicker part is not white and not included).
  double floor_bar() const;
  // Throws std::invalid_argument naming the bad field.
  void validate() const;
};

// The flicker part's value at a global sample index, unit variance (scale by the rms).
double flicker_unit_at(std::uint64_t seed, std::int64_t index);

class PressureChain {
 public:
  PressureChain(const PressureChainConfig& config, const Effects& effects, std::uint64_t seed);
  // True pressure (Pa) of n samples with global indices first_index .. -> measured pressure, in place.
  void measure(std::int64_t first_index, double* pressure_pa, std::size_t n);
  std::uint64_t clipped_samples() const { return adc_.clipped(); }
  const PressureChainConfig& config() const { return config_; }

 private:
  double flicker_at(std::int64_t index);  // flicker_unit_at with the row values cached

  PressureChainConfig config_;
  Effects effects_;
  std::uint64_t seed_;
  Adc adc_;
  std::int64_t row_block_[kFlickerRows];
  double row_value_[kFlickerRows];
  std::int64_t row_offset_[kFlickerRows];
};

}  // namespace noisemon::model::engine
