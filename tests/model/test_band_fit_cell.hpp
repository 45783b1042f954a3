// A synthetic test cell for the band-fitting tests, made without the project's simulation: a periodic cylinder
// pressure (harmonics of the cycle frequency with seeded phases, falling as 1 / (1 + f / corner)) and a microphone
// that hears it through the linear block's steady-state frequency response, written out here from eq. 4.13
// (m z'' = u - k1 z - b1 z', y = c0 z + c1 z'), times an optional extra transfer factor and gain. Whole cycles of
// whole harmonics: the signals are exactly periodic, so the dataset's pre-roll (the first cycle repeated) is the
// signal itself.
#pragma once

#include <cmath>
#include <complex>
#include <cstddef>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "model/block_params.hpp"
#include "model/fit/band_dataset.hpp"

namespace noisemon::model::test_cell {

inline std::complex<double> block_response(const BlockParams& p, double f_hz) {
  const std::complex<double> s(0.0, 2.0 * std::numbers::pi * f_hz);
  return (p.c0 + p.c1 * s) / (p.m * s * s + p.b1 * s + p.k1);
}

struct CellCondition {
  std::string name = "c";
  double rpm = 3000.0;     // 4.8e6 / rpm frames per cycle: must be whole
  std::size_t cycles = 8;  // complete cycles in the recording
  double corner_hz = 500.0;
  double amplitude_pa = 2e5;  // of the first harmonic
  double mean_pa = 1e5;
  double max_hz = 18000.0;  // highest harmonic
  unsigned seed = 1;
  double mic_gain = 1.0;
  std::function<std::complex<double>(double)> extra;  // extra factor on the microphone path (f in Hz); none: 1
  bool motored = false;
};

inline std::size_t cycle_frames(double rpm) {
  return static_cast<std::size_t>(std::lround(fit::kDatasetRateHz * 120.0 / rpm));
}

// One microphone, no acoustic delay; cycles + 2 cycles of frames (the first and the last are cut as incomplete).
inline fit::ConditionRecording block_recording(const BlockParams& block, const CellCondition& c) {
  const std::size_t n = cycle_frames(c.rpm);
  const double f0 = c.rpm / 120.0;
  std::mt19937 rng(c.seed);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  std::vector<double> u(n, c.mean_pa), y(n, c.mic_gain * block.c0 * c.mean_pa / block.k1);
  for (std::size_t h = 1; h * f0 <= c.max_hz; ++h) {
    const double f = static_cast<double>(h) * f0;
    const double a = c.amplitude_pa / (1.0 + f / c.corner_hz), phi = phase(rng);
    const std::complex<double> g = c.mic_gain * block_response(block, f) * (c.extra ? c.extra(f) : 1.0);
    for (std::size_t i = 0; i < n; ++i) {
      const double x = 2.0 * std::numbers::pi * static_cast<double>(h * i % n) / static_cast<double>(n) + phi;
      u[i] += a * std::cos(x);
      y[i] += a * std::abs(g) * std::cos(x + std::arg(g));
    }
  }
  fit::ConditionRecording r;
  r.mic_count = 1;
  const std::size_t total = (c.cycles + 2) * n;
  for (std::size_t i = 0; i < total; ++i) {
    r.pressure_pa.push_back(u[i % n]);
    r.mics_pa.push_back(y[i % n]);
    r.crank_deg.push_back(-360.0 + 720.0 * static_cast<double>(i % n) / static_cast<double>(n));
  }
  return r;
}

// No pressure-chain floor (a stated floor of 0): the predictions subtract nothing.
inline fit::ConditionInfo cell_info(const CellCondition& c) {
  fit::ConditionInfo info;
  info.name = c.name;
  info.speed_rpm = c.rpm;
  info.motored = c.motored;
  info.pressure_floor_pa = 0.0;
  info.encoder_rate_hz = fit::kDatasetRateHz;
  return info;
}

inline fit::BandDataset block_dataset(const BlockParams& block, const std::vector<CellCondition>& conditions) {
  std::vector<fit::ConditionData> out;
  for (const CellCondition& c : conditions) out.push_back(build_condition(cell_info(c), {block_recording(block, c)}));
  return fit::make_dataset(std::move(out));
}

// Per condition, the bands scored: inside [lo_hz, hi_hz] and holding a harmonic.
inline std::vector<std::vector<char>> scored_bands(const fit::BandDataset& data, double lo_hz = 40.0,
                                                   double hi_hz = 12500.0) {
  std::vector<std::vector<char>> scored(data.conditions.size(), std::vector<char>(data.band_count(), 0));
  for (std::size_t k = 0; k < data.conditions.size(); ++k)
    for (std::size_t b = 0; b < data.band_count(); ++b)
      scored[k][b] =
          data.bands[b].exact_mid_hz >= lo_hz && data.bands[b].exact_mid_hz <= hi_hz && !data.band_line_free(k, b);
  return scored;
}

// Cycle mean of per-cycle band values [c * bands + b].
inline std::vector<double> cycle_mean(const std::vector<double>& per_cycle, std::size_t bands) {
  std::vector<double> mean(bands, 0.0);
  const std::size_t cycles = per_cycle.size() / bands;
  for (std::size_t c = 0; c < cycles; ++c)
    for (std::size_t b = 0; b < bands; ++b) mean[b] += per_cycle[c * bands + b] / static_cast<double>(cycles);
  return mean;
}

inline double db(double ratio) { return 10.0 * std::log10(ratio); }

}  // namespace noisemon::model::test_cell
