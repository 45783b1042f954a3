// The frequency-domain view of a condition (condition_spectrum, band_power_response) against analytic results: the
// Butterworth band's power response at its centre and edges, Parseval for a sum of sines, and each band's taps
// holding the power of the sines its filter passes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "model/fit/band_fit_internal.hpp"
#include "tests/model/test_band_fit_cell.hpp"

namespace noisemon::model {
namespace {

using fit::band_fit_internal::band_power_response;
using fit::band_fit_internal::condition_spectrum;

TEST(BandFitSpectrum, BandResponseIsOneAtTheCentreAndHalfAtTheEdges) {
  const dsp::ThirdOctaveBank bank(fit::kDatasetRateHz, 1);
  int cut = 0;
  for (const dsp::ThirdOctaveBand& band : bank.bands()) {
    const double centre = std::sqrt(band.lower_edge_hz * band.upper_edge_hz);
    EXPECT_NEAR(band_power_response(band, band.lower_edge_hz), 0.5, 1e-12) << band.nominal_hz;
    EXPECT_EQ(band_power_response(band, 0.0), 0.0);
    if (band.nyquist_cut) {
      ++cut;
      EXPECT_NEAR(band_power_response(band, 4.0 * band.lower_edge_hz), 1.0, 1e-9);
      continue;
    }
    EXPECT_NEAR(band_power_response(band, centre), 1.0, 1e-12) << band.nominal_hz;
    EXPECT_NEAR(band_power_response(band, band.upper_edge_hz), 0.5, 1e-12) << band.nominal_hz;
    // 8th order: 48 dB per octave of the band-pass variable x far outside.
    EXPECT_LT(band_power_response(band, 4.0 * band.upper_edge_hz), 1e-6) << band.nominal_hz;
  }
  EXPECT_EQ(cut, 1);
}

// A condition whose pressure is a sum of three sines on whole cycles (and a microphone that does not matter here).
fit::BandDataset three_sines(double a1, double f1, double a2, double f2, double a3, double f3) {
  const std::size_t n = test_cell::cycle_frames(3000.0), cycles = 10;
  fit::ConditionRecording r;
  r.mic_count = 1;
  for (std::size_t i = 0; i < (cycles + 2) * n; ++i) {
    const double t = static_cast<double>(i) / fit::kDatasetRateHz;
    const double w = 2.0 * std::numbers::pi * t;
    r.pressure_pa.push_back(1e5 + a1 * std::sin(w * f1) + a2 * std::sin(w * f2 + 1.0) + a3 * std::sin(w * f3 + 2.0));
    r.mics_pa.push_back(std::sin(w * 1000.0));
    r.crank_deg.push_back(-360.0 + 720.0 * static_cast<double>(i % n) / static_cast<double>(n));
  }
  return fit::make_dataset({build_condition(test_cell::cell_info({}), {r})});
}

TEST(BandFitSpectrum, PowerOfSinesIsConservedAndLandsInTheBandsThatPassThem) {
  // 250 Hz (below the merging into 1/48-octave bins), 1 kHz and 4 kHz (above it).
  const double a1 = 100.0, a2 = 30.0, a3 = 10.0;
  const fit::BandDataset data = three_sines(a1, 250.0, a2, 1000.0, a3, 4000.0);
  const fit::ConditionSpectrum sp = condition_spectrum(data, 0, 8);
  ASSERT_EQ(sp.f_hz.size(), sp.s.size());
  ASSERT_EQ(sp.f_hz.size(), sp.df_hz.size());
  EXPECT_TRUE(sp.floor.empty());  // no floor judged
  // The bins are absolute powers (the pressure floor's share per bin is d df / s): they sum to the sines' power
  // (Parseval), although the 12800 frames are zero-padded to 16384.
  double total = 0.0;
  for (double s : sp.s) total += s;
  const double expected = (a1 * a1 + a2 * a2 + a3 * a3) / 2.0;
  const double scale = total / expected;
  EXPECT_NEAR(scale, 1.0, 2e-3);
  // Each band: the sum of its taps is the power of the sines weighted by the band's response at them; to 1 % in the
  // bands that pass a sine at half power or more, in the skirts (the response changes across the window's main lobe)
  // to 1e-3 of the total.
  int passing = 0;
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    const dsp::ThirdOctaveBand& band = data.bands[b];
    double taps = 0.0;
    for (const fit::ConditionSpectrum::Tap& t : sp.band_taps[b]) taps += t.q;
    const double w1 = band_power_response(band, 250.0), w2 = band_power_response(band, 1000.0),
                 w3 = band_power_response(band, 4000.0);
    const double want = (w1 * a1 * a1 + w2 * a2 * a2 + w3 * a3 * a3) / 2;
    if (std::max({w1, w2, w3}) >= 0.5) {
      ++passing;
      EXPECT_NEAR(taps / scale / want, 1.0, 0.01) << band.nominal_hz << " Hz";
    } else {
      EXPECT_NEAR(taps / scale, want, 1e-3 * expected) << band.nominal_hz << " Hz";
    }
  }
  EXPECT_EQ(passing, 3);
}

TEST(BandFitSpectrum, JudgedFloorIsInterpolatedInLogFrequencyBetweenBandCentres) {
  fit::BandDataset data = three_sines(100.0, 250.0, 30.0, 1000.0, 10.0, 4000.0);
  std::vector<double> density(data.band_count());
  for (std::size_t b = 0; b < density.size(); ++b) density[b] = 1e-6 * static_cast<double>(b + 1);
  data.conditions[0].info.floor_density = density;
  const fit::ConditionSpectrum sp = condition_spectrum(data, 0, 8);
  ASSERT_EQ(sp.floor.size(), sp.f_hz.size());
  for (std::size_t j = 0; j < sp.f_hz.size(); ++j) {
    const double f = sp.f_hz[j];
    for (std::size_t b = 0; b + 1 < data.band_count(); ++b) {
      const double lo = data.bands[b].exact_mid_hz, hi = data.bands[b + 1].exact_mid_hz;
      if (f < lo || f >= hi) continue;
      const double t = std::log(f / lo) / std::log(hi / lo);
      EXPECT_NEAR(sp.floor[j], density[b] + t * (density[b + 1] - density[b]), 1e-15) << f;
    }
  }
}

}  // namespace
}  // namespace noisemon::model
