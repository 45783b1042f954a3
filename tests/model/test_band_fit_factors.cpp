// The extension factors and what applies them (extension_factors, apply_factors) and the measured side
// (measured_ms, condition_gaps, rms_db), against hand-computed values: gains multiply, the noise-driven part is
// subtracted (or, near the floor, the prediction becomes an upper bound), additive noise adds by window length.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"
#include "tests/model/test_band_fit_cell.hpp"

namespace noisemon::model {
namespace {

using fit::kW;

// Two bands, two cycles of unequal window lengths, two microphones.
fit::ConditionData small_condition() {
  fit::ConditionData d;
  d.bands = 2;
  d.mics = 2;
  d.cycles.resize(2);
  for (std::size_t c = 0; c < 2; ++c)
    for (std::size_t w = 0; w < kW; ++w)
      d.win_frames.push_back(100.0 + 10.0 * static_cast<double>(w) + 50.0 * static_cast<double>(c));
  // mic_ms [(c * mics + m) * bands + b]
  d.mic_ms = {1.0, 2.0, 3.0, 4.0,   // cycle 0: mic 0 (bands 0, 1), mic 1
              5.0, 6.0, 7.0, 8.0};  // cycle 1
  return d;
}

TEST(BandFitFactors, ApplyMultipliesSubtractsAndAddsByWindowLength) {
  const fit::ConditionData d = small_condition();
  fit::ConditionFactors f;
  f.mult = {2.0, 0.5};
  f.sub = {0.0, 0.1};  // band 1: 0.1 of noise-driven power, far below kFloorShare of its prediction
  f.add.assign(2, 0.0);
  f.add_win.assign(2 * kW, 0.0);
  for (std::size_t w = 0; w < kW; ++w) f.add_win[1 * kW + w] = static_cast<double>(w);  // band 1 only
  std::vector<double> cycle = {10.0, 20.0, 30.0, 40.0};                                 // [c * bands + b]
  std::vector<double> win(2 * kW * 2, 1.0);                                             // [(c * W + w) * bands + b]
  std::vector<char> upper, upper_win;
  fit::apply_factors(f, d, cycle, &win, &upper, &upper_win);
  for (std::size_t c = 0; c < 2; ++c) {
    double add = 0.0, frames = 0.0;
    for (std::size_t w = 0; w < kW; ++w) {
      add += static_cast<double>(w) * d.win_frames[c * kW + w];
      frames += d.win_frames[c * kW + w];
    }
    const double raw0 = c == 0 ? 10.0 : 30.0, raw1 = c == 0 ? 20.0 : 40.0;
    EXPECT_DOUBLE_EQ(cycle[c * 2 + 0], raw0 * 2.0);
    EXPECT_NEAR(cycle[c * 2 + 1], raw1 * 0.5 - 0.1 + add / frames, 1e-12);
    for (std::size_t w = 0; w < kW; ++w) {
      EXPECT_DOUBLE_EQ(win[(c * kW + w) * 2 + 0], 2.0);
      // Window band 1: 0.5 - 0.1 is above kObservableShare (0.1) of 0.5.
      EXPECT_NEAR(win[(c * kW + w) * 2 + 1], 0.5 - 0.1 + static_cast<double>(w), 1e-12);
    }
  }
  EXPECT_EQ(upper, (std::vector<char>{0, 0}));
  EXPECT_EQ(upper_win, std::vector<char>(2 * kW, 0));
}

TEST(BandFitFactors, NearTheFloorThePredictionBecomesAnUpperBound) {
  const fit::ConditionData d = small_condition();
  fit::ConditionFactors f;
  f.mult = {1.0, 1.0};
  // Band 0: the noise drove 30 % of the prediction (more than kFloorShare, a floor 6 dB down); band 1: 10 %.
  f.sub = {0.3 * 15.0, 0.1 * 30.0};
  f.add.assign(2, 0.0);
  f.add_win.assign(2 * kW, 0.0);
  std::vector<double> cycle = {10.0, 20.0, 20.0, 40.0};  // means 15 and 30
  std::vector<char> upper;
  fit::apply_factors(f, d, cycle, nullptr, &upper);
  EXPECT_EQ(upper, (std::vector<char>{1, 0}));
  // Censored: the prediction less the noise-driven part, plus 30 % of that part.
  EXPECT_NEAR(cycle[0], 10.0 - 4.5 + 0.3 * 4.5, 1e-12);
  EXPECT_NEAR(cycle[2], 20.0 - 4.5 + 0.3 * 4.5, 1e-12);
  EXPECT_NEAR(cycle[1], 20.0 - 3.0, 1e-12);
  EXPECT_NEAR(cycle[3], 40.0 - 3.0, 1e-12);
}

TEST(BandFitFactors, StationaryAndLockedNoiseAddTheirMeanSquaresScaledBySpeed) {
  const fit::BandDataset data = test_cell::block_dataset(preset("linear"), {test_cell::CellCondition{}});  // 3000 rpm
  const fit::ConditionSpectrum spec = fit::band_fit_internal::condition_spectrum(data, 0, 8);
  const std::size_t nb = data.band_count();
  fit::ExtendedModel m;
  m.block = preset("linear");
  m.on.stationary = m.on.locked = true;
  m.ext.speed_ref_rpm = 2000.0;
  m.ext.locked_speed_exp = 2.0;  // (3000 / 2000)^2 = 2.25
  m.ext.stationary_ms.assign(nb, 0.0);
  m.ext.locked_ms.assign(nb * kW, 0.0);
  m.ext.stationary_ms[20] = 1.5;
  for (std::size_t w = 0; w < kW; ++w) m.ext.locked_ms[20 * kW + w] = static_cast<double>(w + 1);
  const fit::ConditionFactors f = extension_factors(data, 0, spec, m.block, m);
  const fit::ConditionData& cond = data.conditions[0];
  double frames = 0.0, locked = 0.0;
  std::vector<double> share(kW, 0.0);
  for (std::size_t c = 0; c < cond.cycle_count(); ++c)
    for (std::size_t w = 0; w < kW; ++w) {
      share[w] += cond.win_frames[c * kW + w];
      frames += cond.win_frames[c * kW + w];
    }
  for (std::size_t w = 0; w < kW; ++w) {
    EXPECT_NEAR(f.add_win[20 * kW + w], 1.5 + 2.25 * static_cast<double>(w + 1), 1e-12);
    locked += 2.25 * static_cast<double>(w + 1) * share[w] / frames;
  }
  EXPECT_NEAR(f.add[20], 1.5 + locked, 1e-12);
  for (std::size_t b = 0; b < nb; ++b) {
    EXPECT_DOUBLE_EQ(f.mult[b], 1.0);  // no structural change
    EXPECT_EQ(f.sub[b], 0.0);          // no floor, no transducer
    if (b != 20) {
      EXPECT_EQ(f.add[b], 0.0);
    }
  }
}

TEST(BandFitFactors, MicrophoneGainsCorrectTheMeasurementAndTheGapIsItsDbRatio) {
  const fit::ConditionData d = small_condition();
  fit::ExtendedModel m;
  EXPECT_DOUBLE_EQ(fit::measured_ms(d, 1, 0, m), (5.0 + 7.0) / 2);
  m.on.mic_gain = true;
  m.ext.mic_gain_db = {10.0, -10.0};  // mic 0 reads 10 dB high, mic 1 10 dB low
  EXPECT_NEAR(fit::measured_ms(d, 1, 0, m), (5.0 / 10.0 + 7.0 * 10.0) / 2, 1e-12);
  m.ext.mic_gain_db = {10.0};  // not one per microphone: ignored
  EXPECT_DOUBLE_EQ(fit::measured_ms(d, 1, 0, m), (5.0 + 7.0) / 2);
  const fit::ExtendedModel plain;
  const std::vector<double> pred = {1.0, 2.0, 3.0, 4.0};  // [c * bands + b]
  const std::vector<double> gaps = fit::condition_gaps(d, pred, {1, 0}, plain);
  EXPECT_NEAR(gaps[0], 10.0 * std::log10((2.0 + 6.0) / (1.0 + 3.0)), 1e-12);
  EXPECT_TRUE(std::isnan(gaps[1]));  // not scored
  EXPECT_NEAR(fit::rms_db({3.0, std::numeric_limits<double>::quiet_NaN(), -4.0}), std::sqrt(12.5), 1e-12);
  EXPECT_TRUE(std::isnan(fit::rms_db({std::numeric_limits<double>::quiet_NaN()})));
}

}  // namespace
}  // namespace noisemon::model
