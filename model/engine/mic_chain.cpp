#include "model/engine/mic_chain.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "dsp/levels.hpp"
#include "dsp/weighting.hpp"
#include "model/engine/random.hpp"

namespace noisemon::model::engine {

namespace {

constexpr double kQ = 1.0;  // broad peaks (1.9 octaves between the half-gain points): neighbours overlap smoothly
constexpr double kSpreadCornerHz = 1000.0;  // sigma(f) = D sqrt(f / (f + corner))
constexpr int kNormaliseIterations = 20;    // band-centre energy normalisation (a contraction: ~1e-9 dB left)
constexpr std::uint64_t kStreamDirectivity = 0x5001;

bool band_used(std::size_t k, double fs_hz) { return kDirectivityBandsHz[k] < 0.45 * fs_hz; }

}  // namespace

void MicChainConfig::validate() const {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("microphone chain: " + what); };
  if (!(self_noise_dba <= 120.0)) fail("self_noise_dba must be at most 120 dB(A) (-inf: none)");
  if (!(directivity_db >= 0.0 && directivity_db <= 6.0)) fail("directivity_db must be in [0, 6]");
  if (adc_bits != 0 && (adc_bits < 4 || adc_bits > 32)) fail("adc_bits must be 0 (no ADC) or 4 .. 32");
  if (adc_bits != 0 && !(adc_range_pa > 0.0)) fail("adc_range_pa must be positive");
}

double directivity_spread_db(double directivity_db, double f_hz) {
  return directivity_db * std::sqrt(f_hz / (f_hz + kSpreadCornerHz));
}

std::vector<std::array<double, kDirectivityBands>> directivity_gains_db(std::size_t mics, double directivity_db,
                                                                        double fs_hz, std::uint64_t setup_seed) {
  std::vector<std::array<double, kDirectivityBands>> g(mics, std::array<double, kDirectivityBands>{});
  if (directivity_db == 0.0 || mics == 0) return g;
  for (std::size_t i = 0; i < mics; ++i)
    for (std::size_t k = 0; k < kDirectivityBands; ++k)
      if (band_used(k, fs_hz))
        g[i][k] = directivity_spread_db(directivity_db, kDirectivityBandsHz[k]) *
                  rnd::normal_at(setup_seed, kStreamDirectivity, i * kDirectivityBands + k);
  // The peaks overlap, so a band centre also hears its neighbours: shift each band's gains (the same for every
  // microphone) until the energy mean of the cascades' responses at every centre is 1.
  for (int it = 0; it < kNormaliseIterations; ++it) {
    std::array<double, kDirectivityBands> mean{};
    for (std::size_t i = 0; i < mics; ++i) {
      const DirectivityFilter f(g[i], fs_hz);
      for (std::size_t k = 0; k < kDirectivityBands; ++k)
        if (band_used(k, fs_hz)) mean[k] += std::norm(f.response(kDirectivityBandsHz[k])) / static_cast<double>(mics);
    }
    for (std::size_t k = 0; k < kDirectivityBands; ++k)
      if (band_used(k, fs_hz))
        for (std::size_t i = 0; i < mics; ++i) g[i][k] -= 10.0 * std::log10(mean[k]);
  }
  return g;
}

DirectivityFilter::DirectivityFilter(const std::array<double, kDirectivityBands>& gains_db, double fs_hz) : fs_(fs_hz) {
  for (std::size_t k = 0; k < kDirectivityBands; ++k) {
    if (!band_used(k, fs_hz) || gains_db[k] == 0.0) continue;
    // RBJ audio-EQ cookbook peaking filter: gain 10^(G/20) at f0, unity far from it.
    const double a = std::pow(10.0, gains_db[k] / 40.0);
    const double w0 = 2.0 * kPi * kDirectivityBandsHz[k] / fs_hz;
    const double alpha = std::sin(w0) / (2.0 * kQ);
    const double a0 = 1.0 + alpha / a;
    Section& s = sections_[count_++];
    s.b0 = (1.0 + alpha * a) / a0;
    s.b1 = -2.0 * std::cos(w0) / a0;
    s.b2 = (1.0 - alpha * a) / a0;
    s.a1 = s.b1;
    s.a2 = (1.0 - alpha / a) / a0;
  }
}

double DirectivityFilter::process(double x) {
  for (std::size_t k = 0; k < count_; ++k) {
    Section& s = sections_[k];
    const double y = s.b0 * x + s.b1 * s.x1 + s.b2 * s.x2 - s.a1 * s.y1 - s.a2 * s.y2;
    s.x2 = s.x1;
    s.x1 = x;
    s.y2 = s.y1;
    s.y1 = y;
    x = y;
  }
  return x;
}

std::complex<double> DirectivityFilter::response(double f_hz) const {
  const std::complex<double> z1 = std::polar(1.0, -2.0 * kPi * f_hz / fs_);  // z^-1
  std::complex<double> h = 1.0;
  for (std::size_t k = 0; k < count_; ++k) {
    const Section& s = sections_[k];
    h *= (s.b0 + s.b1 * z1 + s.b2 * z1 * z1) / (1.0 + s.a1 * z1 + s.a2 * z1 * z1);
  }
  return h;
}

double self_noise_rms_pa(double level_dba, double fs_hz) {
  // White noise of variance s^2 has the one-sided density 2 s^2 / fs; its A-weighted power is that times the
  // integral of the A-weighting's power gain (trapezoid on a 1 Hz grid).
  const double f_lo = 20.0, f_hi = std::min(20000.0, 0.5 * fs_hz);
  const auto n = static_cast<std::size_t>(std::ceil(f_hi - f_lo));
  const double df = (f_hi - f_lo) / static_cast<double>(n);
  double gain = 0.0;
  for (std::size_t i = 0; i <= n; ++i) {
    const double f = f_lo + df * static_cast<double>(i);
    gain += (i == 0 || i == n ? 0.5 : 1.0) * std::pow(10.0, dsp::a_weighting_db(f) / 10.0) * df;
  }
  return std::sqrt(dsp::mean_square_from_level(level_dba) * fs_hz / (2.0 * gain));
}

}  // namespace noisemon::model::engine
