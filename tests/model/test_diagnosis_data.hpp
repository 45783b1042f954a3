// Band datasets with a known answer for the unit tests of the diagnosis stages (tests/model/test_diagnosis_*.cpp).
//
// Every recording is strictly periodic: one engine cycle (a combustion pulse, a ringing and a seeded white part)
// repeated, so the block's steady-state response is exactly periodic too. The microphones hear that response,
// computed here without the project's integrator: the DFT of one cycle times the transfer function of eq. 4.13's
// linear part, H(f) = (C1 s + C0) / (m s^2 + b1 s + k1), written out below.
#pragma once

#include <cmath>
#include <complex>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "model/block_params.hpp"
#include "model/fit/band_dataset.hpp"

namespace noisemon::model::testdata {

inline constexpr double kFs = fit::kDatasetRateHz;

// One cycle of cylinder pressure (Pa) at `rpm`: ambient, a pulse near TDC, a ringing after it and white noise.
inline std::vector<double> pressure_cycle(double rpm, double scale, std::uint64_t seed) {
  const auto n = static_cast<std::size_t>(std::lround(kFs * 120.0 / rpm));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> white(0.0, 2e3);
  std::vector<double> p(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double deg = -360.0 + 720.0 * static_cast<double>(i) / static_cast<double>(n);
    const double t = static_cast<double>(i) / kFs;
    const double pulse = 40e5 * std::exp(-std::pow((deg - 5.0) / 25.0, 2));
    const double ring =
        deg > 5.0 ? 1e4 * std::exp(-(deg - 5.0) / 40.0) * std::sin(2 * std::numbers::pi * 6000.0 * t) : 0.0;
    p[i] = 1e5 + scale * (pulse + ring + white(rng));
  }
  return p;
}

// Periodic steady-state response of the linear block to one period x (exact for a band-limited periodic input).
inline std::vector<double> periodic_block_response(const BlockParams& q, const std::vector<double>& x) {
  const std::size_t n = x.size();
  std::vector<std::complex<double>> twiddle(n);  // exp(-2 pi i j / n)
  for (std::size_t j = 0; j < n; ++j)
    twiddle[j] = std::polar(1.0, -2.0 * std::numbers::pi * static_cast<double>(j) / static_cast<double>(n));
  std::vector<std::complex<double>> spec(n / 2 + 1);
  for (std::size_t k = 0; k <= n / 2; ++k) {
    std::complex<double> s = 0.0;
    for (std::size_t i = 0; i < n; ++i) s += x[i] * twiddle[k * i % n];
    const std::complex<double> jw(0.0, 2.0 * std::numbers::pi * kFs * static_cast<double>(k) / static_cast<double>(n));
    spec[k] = s * (q.c1 * jw + q.c0) / (q.m * jw * jw + q.b1 * jw + q.k1);
  }
  std::vector<double> y(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    double acc = spec[0].real();
    for (std::size_t k = 1; k <= n / 2; ++k) {
      const double w = (n % 2 == 0 && k == n / 2) ? 1.0 : 2.0;
      acc += w * (spec[k] * std::conj(twiddle[k * i % n])).real();
    }
    y[i] = acc / static_cast<double>(n);
  }
  return y;
}

// Seeded white noise, `n` samples of rms `sigma`.
inline std::vector<double> white_noise(std::size_t n, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, sigma);
  std::vector<double> w(n);
  for (double& x : w) x = g(rng);
  return w;
}

// A condition made of a repeated pressure cycle, with microphones given per cycle sample (mic_cycles: one period
// per microphone, repeated like the pressure), plus optional aperiodic additions over the whole recording.
struct Recipe {
  fit::ConditionInfo info;
  std::vector<double> pressure_cycle;
  std::vector<std::vector<double>> mic_cycles;  // per microphone, one period
  std::vector<std::vector<double>> mic_extra;   // per microphone, the whole recording (empty: none)
  std::vector<double> pressure_extra;           // the whole recording (empty: none)
  std::size_t cycles = 8;
  // The recording starts half a cycle in; without the lead-in it starts on a cycle boundary, where a background
  // run (engine off: cut into blocks of 1600 frames from its start) is cut too.
  bool half_cycle_lead_in = true;
};

inline std::size_t recording_frames(const Recipe& r) { return (r.cycles + 1) * r.pressure_cycle.size(); }

// The first complete cycle begins at the first wrap of the crank angle.
inline fit::ConditionData build(const Recipe& r) {
  const std::size_t n = r.pressure_cycle.size(), frames = recording_frames(r), mics = r.mic_cycles.size();
  fit::ConditionRecording rec;
  rec.mic_count = mics;
  rec.pressure_pa.resize(frames);
  rec.crank_deg.resize(frames);
  rec.mics_pa.resize(frames * mics);
  for (std::size_t f = 0; f < frames; ++f) {
    const std::size_t i = (f + (r.half_cycle_lead_in ? n / 2 : 0)) % n;
    rec.pressure_pa[f] = r.pressure_cycle[i] + (r.pressure_extra.empty() ? 0.0 : r.pressure_extra[f]);
    rec.crank_deg[f] = -360.0 + 720.0 * static_cast<double>(i) / static_cast<double>(n);
    for (std::size_t m = 0; m < mics; ++m)
      rec.mics_pa[f * mics + m] = r.mic_cycles[m][i] + (r.mic_extra.empty() ? 0.0 : r.mic_extra[m][f]);
  }
  return build_condition(r.info, {rec});
}

// A condition's info with an ideal pressure chain (a stated floor of 0: nothing is floor-limited by it).
inline fit::ConditionInfo ideal_info(const std::string& name, double rpm) {
  fit::ConditionInfo i;
  i.name = name;
  i.speed_rpm = rpm;
  i.pressure_floor_pa = 0.0;
  i.encoder_rate_hz = kFs;
  return i;
}

// A fired condition whose microphones hear the block `truth` exactly, each with a gain (dB) of its own.
inline Recipe fired(const std::string& name, double rpm, double scale, const BlockParams& truth,
                    const std::vector<double>& mic_gain_db, std::uint64_t seed) {
  Recipe r;
  r.info = ideal_info(name, rpm);
  r.pressure_cycle = pressure_cycle(rpm, scale, seed);
  const std::vector<double> y = periodic_block_response(truth, r.pressure_cycle);
  for (double g : mic_gain_db) {
    std::vector<double> m = y;
    for (double& x : m) x *= std::pow(10.0, g / 20.0);
    r.mic_cycles.push_back(std::move(m));
  }
  return r;
}

}  // namespace noisemon::model::testdata
