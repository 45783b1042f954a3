// Welch spectra and the 1/3-octave rms from them, against closed forms: a sine's rms is its amplitude over sqrt 2,
// all in its own band; white noise's mean square is its variance, spread over the bands in proportion to their
// width (the width of the spectrum's bins in each band); a signal's cross spectrum with twice itself is twice its
// auto spectrum.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "dsp/welch.hpp"

using namespace noisemon;

namespace {

std::vector<std::vector<double>> sine_segments(double amplitude, double f_hz, double fs_hz, int segments, int n) {
  std::vector<std::vector<double>> out(segments, std::vector<double>(n));
  for (int s = 0; s < segments; ++s)
    for (int i = 0; i < n; ++i)
      out[s][i] = amplitude * std::sin(2 * std::numbers::pi * f_hz * (s * 1.7 + i / fs_hz) + 0.3 * s);
  return out;
}

}  // namespace

TEST(Welch, ASinesRmsIsItsAmplitudeOverRootTwoInItsOwnBand) {
  const double fs = 10000.0, amplitude = 3.0;
  const auto x = sine_segments(amplitude, 1000.0, fs, 4, 8192);
  const std::vector<dsp::BandRms> bands = dsp::third_octave_rms(x, fs);
  ASSERT_FALSE(bands.empty());
  int found = 0;
  for (const dsp::BandRms& b : bands) {
    EXPECT_NEAR(b.f_hi_hz / b.f_lo_hz, std::pow(10.0, 0.1), 1e-12);
    if (std::abs(b.f_center_hz - 1000.0) < 1e-9) {
      EXPECT_NEAR(b.rms, amplitude / std::sqrt(2.0), 0.01 * amplitude / std::sqrt(2.0));
      ++found;
    } else if (b.f_hi_hz < 800.0 || b.f_lo_hz > 1250.0) {
      EXPECT_LT(b.rms, 0.01 * amplitude) << b.f_center_hz << " Hz";  // a band away from it: the window's leakage
    }
  }
  EXPECT_EQ(found, 1);
}

TEST(Welch, WhiteNoisesMeanSquareIsItsVarianceSpreadByBandwidth) {
  const double fs = 1000.0, sigma = 0.7;
  std::mt19937_64 gen(7);
  std::normal_distribution<double> noise(0.0, sigma);
  std::vector<std::vector<double>> x(8, std::vector<double>(40000));
  for (auto& segment : x)
    for (double& v : segment) v = noise(gen);
  const std::vector<dsp::BandRms> bands = dsp::third_octave_rms(x, fs);
  ASSERT_GT(bands.size(), 10u);
  // The spectrum's bins are fs/nfft wide; a band holds the bins whose frequency falls in it, so a white spectrum
  // puts sigma^2 times (its bins' width over fs/2) in it (in the narrow low bands that is not the band's width).
  const double df = fs / static_cast<double>(dsp::welch_nfft(x));
  double total_ms = 0.0, total_expected = 0.0;
  for (std::size_t k = 0; k < bands.size(); ++k) {
    if (k > 0 && bands[k].f_center_hz < 1.3 * bands[k - 1].f_center_hz)  // neighbours (a binless band is left out)
      EXPECT_NEAR(bands[k].f_lo_hz, bands[k - 1].f_hi_hz, 1e-9 * bands[k].f_lo_hz);
    int bins = 0;
    for (int i = 1; i * df <= fs / 2; ++i) bins += i * df >= bands[k].f_lo_hz && i * df < bands[k].f_hi_hz;
    const double expected = sigma * sigma * bins * df / (fs / 2);
    const double ms = bands[k].rms * bands[k].rms;
    // 144 windows: a bin's estimate spreads by about a tenth; a band of many bins much less.
    EXPECT_NEAR(ms, expected, (bins < 4 ? 0.4 : 0.15) * expected) << bands[k].f_center_hz << " Hz, " << bins << " bins";
    total_ms += ms;
    total_expected += expected;
  }
  EXPECT_NEAR(total_ms, total_expected, 0.03 * total_expected);
}

TEST(Welch, TheCrossSpectrumWithTwiceASignalIsTwiceItsAutoSpectrum) {
  std::mt19937_64 gen(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<std::vector<double>> a(3, std::vector<double>(5000)), b = a;
  for (std::size_t s = 0; s < a.size(); ++s)
    for (std::size_t i = 0; i < a[s].size(); ++i) b[s][i] = 2.0 * (a[s][i] = noise(gen));
  const std::size_t nfft = dsp::welch_nfft(a);
  EXPECT_EQ(nfft, 1024u);  // a quarter of 5000, a power of two
  std::vector<std::complex<double>> sab;
  std::vector<double> saa;
  // Windows of 1024 every 512 samples: 8 in each 5000-sample segment.
  EXPECT_EQ(dsp::welch(a, b, nfft, sab, saa), 3u * 8u);
  ASSERT_EQ(sab.size(), nfft / 2 + 1);
  for (std::size_t k = 0; k < sab.size(); ++k) {
    EXPECT_NEAR(sab[k].real(), 2.0 * saa[k], 1e-9 * saa[k] + 1e-12);
    EXPECT_NEAR(sab[k].imag(), 0.0, 1e-9 * saa[k] + 1e-12);
  }
}
