// The attribution of a change on the synthetic cell (synthetic_gap_cell.hpp: effects added as powers, the way the
// physics adds them, not as the candidates' dB formulas): each effect named with its parameters, a change outside the
// catalogue left unexplained.
#include "model/diagnosis/change_attribution.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>

#include "tests/model/synthetic_gap_cell.hpp"

namespace nm = noisemon::model;

namespace {

// Means over 400 cycles before and 400 after, standard errors from the cycles' own spread.
nm::diagnosis::GapChange change_of(const gapcell::Effects& effects, unsigned seed = 9) {
  gapcell::Cell cell(seed);
  constexpr int kCycles = 400;
  const std::size_t nb = gapcell::kBandsHz.size(), nm_ = gapcell::kMics;
  nm::diagnosis::GapChange g;
  g.band_hz = gapcell::kBandsHz;
  g.band_used.assign(nb, 1);
  g.speed_rpm = 3050.0;
  g.pressure_edge_rate_hz = 3600.0 * 3050.0 / 60.0;
  auto average = [&](const gapcell::Effects& e, std::vector<double>& meas, std::vector<double>& pred,
                     std::vector<double>& cpl, std::vector<double>& mic, std::vector<double>* gap_sd) {
    meas.assign(nb, 0.0), pred.assign(nb, 0.0), cpl.assign(nb, 0.0), mic.assign(nm_, 0.0);
    std::vector<double> ss(nb, 0.0);
    for (int i = 0; i < kCycles; ++i) {
      const nm::diagnosis::CycleGap c = cell.next(e);
      for (std::size_t b = 0; b < nb; ++b) {
        meas[b] += c.measured_db[b] / kCycles, pred[b] += c.predicted_db[b] / kCycles, cpl[b] += c.cpl_db[b] / kCycles;
        ss[b] += std::pow(c.measured_db[b] - c.predicted_db[b], 2) / kCycles;
      }
      for (std::size_t m = 0; m < nm_; ++m) mic[m] += c.mic_db[m] / kCycles;
    }
    if (gap_sd)
      for (std::size_t b = 0; b < nb; ++b)
        gap_sd->push_back(std::sqrt(std::max(0.0, ss[b] - std::pow(meas[b] - pred[b], 2))));
  };
  std::vector<double> sd;
  average({}, g.measured_before, g.predicted_before, g.cpl_before, g.mic_before, &sd);
  average(effects, g.measured_after, g.predicted_after, g.cpl_after, g.mic_after, nullptr);
  for (const double s : sd) g.band_sigma_db.push_back(s * std::sqrt(2.0 / kCycles));
  g.cpl_sigma_db = g.band_sigma_db;
  g.mic_sigma_db.assign(nm_, 0.05);
  return g;
}

double param(const nm::diagnosis::Attribution& a, const std::string& key) {
  for (const auto& [k, v] : a.params)
    if (k == key) return v;
  ADD_FAILURE() << "no parameter " << key << " of " << a.effect;
  return NAN;
}

double bandwidth(double hz) { return hz * (std::pow(10.0, 0.05) - std::pow(10.0, -0.05)); }

}  // namespace

TEST(ChangeAttribution, MicrophoneGain) {
  gapcell::Effects e;
  e.gain_mic = 6;
  e.gain_db = 3.0;
  const nm::diagnosis::Attribution a = nm::diagnosis::attribute_change(change_of(e));
  EXPECT_EQ(a.effect, "mic_gain") << a.explanation;
  EXPECT_EQ(param(a, "mic"), 7.0);
  EXPECT_NEAR(param(a, "db"), 3.0, 0.2);
}

// White noise of 0.2 bar rms per sample of a 0.1 deg encoder at 3050 rpm in the measured pressure.
TEST(ChangeAttribution, TransducerNoise) {
  gapcell::Effects e;
  const double edge_rate = 3600.0 * 3050.0 / 60.0, sigma_pa = 0.2e5;
  e.transducer_pa2_per_hz = 2.0 * sigma_pa * sigma_pa / edge_rate;
  const nm::diagnosis::Attribution a = nm::diagnosis::attribute_change(change_of(e));
  EXPECT_EQ(a.effect, "transducer_noise") << a.explanation;
  EXPECT_NEAR(param(a, "bar"), 0.2, 0.03);
}

// A structural resonance: the band's mean of |1 + a R|^2 integrated here on a fine linear grid, +6 dB at 3150 Hz, Q 5.
TEST(ChangeAttribution, SecondMode) {
  gapcell::Effects e;
  const double a_gain = std::pow(10.0, 6.0 / 20.0) - 1.0, f2 = 3150.0, q = 5.0;
  for (const double hz : gapcell::kBandsHz) {
    double sum = 0.0;
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
      const double f = hz * std::pow(10.0, -0.05) + bandwidth(hz) * (i + 0.5) / n;
      const std::complex<double> s(0.0, f / f2);
      sum += std::norm(1.0 + a_gain * (s / q) / (1.0 + s / q + s * s)) / n;
    }
    e.structure_db.push_back(10.0 * std::log10(sum));
  }
  const nm::diagnosis::Attribution a = nm::diagnosis::attribute_change(change_of(e));
  EXPECT_EQ(a.effect, "second_mode") << a.explanation;
  EXPECT_NEAR(std::log2(param(a, "hz") / f2), 0.0, 1.0 / 6.0);
  EXPECT_NEAR(param(a, "db"), 6.0, 1.5);
}

TEST(ChangeAttribution, UniformStructuralGain) {
  gapcell::Effects e;
  e.structure_db.assign(gapcell::kBandsHz.size(), 1.5);
  const nm::diagnosis::Attribution a = nm::diagnosis::attribute_change(change_of(e));
  EXPECT_EQ(a.effect, "speed_dependence") << a.explanation;
  EXPECT_NEAR(param(a, "gain_db"), 1.5, 0.1);
}

// Additive sound at every microphone, low (ventilation: 60 dB per band below 500 Hz over the cell's ~60-70 dB there)
// and high (impacts: 4-8 kHz); without crank windows the spectrum's centre names them.
TEST(ChangeAttribution, AdditiveNoiseLowAndHigh) {
  gapcell::Effects low, high;
  const double p0 = 4e-10;
  for (const double hz : gapcell::kBandsHz) {
    low.additive_pa2.push_back(hz <= 500.0 ? p0 * std::pow(10.0, 9.2) : 0.0);
    high.additive_pa2.push_back(hz >= 4000.0 ? p0 * std::pow(10.0, 9.5) : 0.0);
  }
  const nm::diagnosis::Attribution a = nm::diagnosis::attribute_change(change_of(low));
  EXPECT_EQ(a.effect, "background_noise") << a.explanation;
  const nm::diagnosis::Attribution b = nm::diagnosis::attribute_change(change_of(high));
  EXPECT_EQ(b.effect, "mechanical_noise") << b.explanation;
}

// Bands alternately 2 dB up and down: nothing in the catalogue makes that comb.
TEST(ChangeAttribution, ACombOutsideTheCatalogueIsUnexplained) {
  gapcell::Effects e;
  for (std::size_t b = 0; b < gapcell::kBandsHz.size(); ++b) e.structure_db.push_back(b % 2 ? 2.0 : -2.0);
  const nm::diagnosis::Attribution a = nm::diagnosis::attribute_change(change_of(e));
  EXPECT_EQ(a.effect, "unexplained") << a.explanation;
  EXPECT_EQ(a.confidence, 0.0);
}
