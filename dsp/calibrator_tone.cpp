#include "dsp/calibrator_tone.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace noisemon::dsp {
namespace {

constexpr double kBlockS = 0.01;  // demodulation blocks: a 100 Hz wide look at the tone

// The mean of samples * exp(-i 2 pi f t) over each block of `block` samples.
std::vector<std::complex<double>> demodulate(std::span<const double> x, double rate_hz, double f_hz,
                                             std::size_t block) {
  std::vector<std::complex<double>> out;
  const double w = 2.0 * std::numbers::pi * f_hz / rate_hz;
  for (std::size_t start = 0; start + block <= x.size(); start += block) {
    std::complex<double> sum = 0;
    for (std::size_t k = start; k < start + block; ++k) sum += x[k] * std::polar(1.0, -w * static_cast<double>(k));
    out.push_back(sum / static_cast<double>(block));
  }
  return out;
}

// The frequency offset whose phase advance the blocks show: least-squares slope of their unwrapped phase.
double phase_slope_hz(const std::vector<std::complex<double>>& z, double block_s) {
  std::vector<double> phase(z.size());
  for (std::size_t b = 0; b < z.size(); ++b) {
    phase[b] = std::arg(z[b]);
    if (b > 0) phase[b] = phase[b - 1] + std::remainder(phase[b] - phase[b - 1], 2.0 * std::numbers::pi);
  }
  const double n = static_cast<double>(z.size()), mean_b = (n - 1) / 2;
  double mean_p = 0;
  for (double p : phase) mean_p += p / n;
  double num = 0, den = 0;
  for (std::size_t b = 0; b < z.size(); ++b) {
    num += (static_cast<double>(b) - mean_b) * (phase[b] - mean_p);
    den += (static_cast<double>(b) - mean_b) * (static_cast<double>(b) - mean_b);
  }
  return num / den / (2.0 * std::numbers::pi * block_s);
}

}  // namespace

ToneMeasurement measure_tone(std::span<const double> x, double rate_hz, double nominal_hz) {
  if (!(rate_hz > 0) || !(nominal_hz > 0) || nominal_hz >= rate_hz / 2)
    throw std::invalid_argument("measure_tone: the tone must lie below half the sample rate");
  if (static_cast<double>(x.size()) < rate_hz)
    throw std::invalid_argument("measure_tone: at least one second of samples is needed");
  const auto block = static_cast<std::size_t>(std::lround(kBlockS * rate_hz));
  const double block_s = static_cast<double>(block) / rate_hz;
  ToneMeasurement m;
  m.frequency_hz = nominal_hz + phase_slope_hz(demodulate(x, rate_hz, nominal_hz, block), block_s);
  const std::vector<std::complex<double>> z = demodulate(x, rate_hz, m.frequency_hz, block);
  // Amplitude 2 |mean| per block; the whole tone's rms from the mean power of its blocks.
  double power = 0;
  for (const auto& c : z) power += 2.0 * std::norm(c) / static_cast<double>(z.size());
  m.rms = std::sqrt(power);
  const std::size_t per_half = static_cast<std::size_t>(std::lround(0.5 / block_s));
  double lowest = INFINITY, highest = -INFINITY;
  for (std::size_t start = 0; start + per_half <= z.size(); start += per_half, ++m.half_seconds) {
    double p = 0;
    for (std::size_t b = start; b < start + per_half; ++b) p += 2.0 * std::norm(z[b]) / static_cast<double>(per_half);
    lowest = std::min(lowest, 10.0 * std::log10(p));
    highest = std::max(highest, 10.0 * std::log10(p));
  }
  m.fluctuation_db = highest - lowest;
  double total = 0;
  for (double v : x) total += v * v;
  m.total_rms = std::sqrt(total / static_cast<double>(x.size()));
  return m;
}

}  // namespace noisemon::dsp
