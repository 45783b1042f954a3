// The band dataset (build_condition, make_dataset) against analytic signals: a sine's band levels (A^2 / 2 in the
// band whose centre it sits at, the bank's gain there being 1), cycles cut where the crank angle wraps, crank
// windows of 90 degrees, microphones paired with the pressure across the acoustic delay, the flags of bands without
// a cycle harmonic, the coherence of a periodic signal, and the errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "model/fit/band_dataset.hpp"
#include "tests/model/test_band_fit_cell.hpp"

namespace noisemon::model {
namespace {

using fit::kW;

// A sine of amplitude a at f Hz on the pressure (around 1 bar) and, times g, on `mics` microphones; the crank angle
// of an engine at rpm; `cycles` + 2 cycles of frames.
fit::ConditionRecording sine_recording(double a, double f, double g, std::size_t mics, double rpm, std::size_t cycles) {
  const std::size_t n = test_cell::cycle_frames(rpm);
  fit::ConditionRecording r;
  r.mic_count = mics;
  const std::size_t frames = (cycles + 2) * n;
  for (std::size_t i = 0; i < frames; ++i) {
    const double x = a * std::sin(2.0 * std::numbers::pi * f * static_cast<double>(i) / fit::kDatasetRateHz);
    r.pressure_pa.push_back(1e5 + x);
    r.crank_deg.push_back(-360.0 + 720.0 * static_cast<double>(i % n) / static_cast<double>(n));
  }
  for (std::size_t i = 0; i < frames; ++i)
    for (std::size_t m = 0; m < mics; ++m)
      r.mics_pa.push_back(g * (r.pressure_pa[i] - 1e5) * static_cast<double>(m + 1));
  return r;
}

fit::ConditionInfo info(const std::string& name, double rpm) {
  test_cell::CellCondition c;
  c.name = name;
  c.rpm = rpm;
  return test_cell::cell_info(c);
}

std::size_t band_at(const std::vector<dsp::ThirdOctaveBand>& bands, double nominal_hz) {
  for (std::size_t b = 0; b < bands.size(); ++b)
    if (bands[b].nominal_hz == nominal_hz) return b;
  return bands.size();
}

TEST(BandDataset, SineAtABandCentreReadsHalfItsSquaredAmplitudeThere) {
  const dsp::ThirdOctaveBank bank(fit::kDatasetRateHz, 1);
  const std::size_t b1k = band_at(bank.bands(), 1000.0);
  ASSERT_LT(b1k, bank.band_count());
  const double f = bank.bands()[b1k].exact_mid_hz, a = 200.0, g = 0.01;
  const fit::ConditionData d = build_condition(info("sine", 3000.0), {sine_recording(a, f, g, 2, 3000.0, 6)});
  ASSERT_EQ(d.cycle_count(), 6u);
  for (std::size_t c = 0; c < d.cycle_count(); ++c) {
    EXPECT_NEAR(test_cell::db(d.cpl_ms[c * d.bands + b1k] / (a * a / 2)), 0.0, 0.05) << "cycle " << c;
    // Microphone m hears (m + 1) g times the sine.
    for (std::size_t m = 0; m < 2; ++m) {
      const double want = std::pow(g * static_cast<double>(m + 1) * a, 2) / 2;
      EXPECT_NEAR(test_cell::db(d.mic_ms[(c * 2 + m) * d.bands + b1k] / want), 0.0, 0.05);
    }
    const double mic0 = d.mic_ms[(c * 2) * d.bands + b1k], mic1 = d.mic_ms[(c * 2 + 1) * d.bands + b1k];
    EXPECT_NEAR(d.mic_avg_ms(c, b1k), (mic0 + mic1) / 2, 1e-15);
    // Two octaves away the band holds almost nothing (the 8th-order filter).
    EXPECT_LT(d.cpl_ms[c * d.bands + band_at(bank.bands(), 250.0)], 1e-6 * a * a);
    EXPECT_LT(d.cpl_ms[c * d.bands + band_at(bank.bands(), 4000.0)], 1e-6 * a * a);
  }
}

TEST(BandDataset, CyclesAreCutAtTheCrankWrapAndSplitIntoNinetyDegreeWindows) {
  const double rpm = 2400.0;  // 2000 frames per cycle
  const fit::ConditionData d = build_condition(info("cut", rpm), {sine_recording(10.0, 1000.0, 1.0, 1, rpm, 5)});
  ASSERT_EQ(d.cycle_count(), 5u);
  ASSERT_EQ(d.segments.size(), 1u);
  const fit::PreparedSegment& s = d.segments[0];
  EXPECT_EQ(fit::segment_cycles(s), 5u);
  EXPECT_EQ(s.data_start, 4u * 2000u);  // four cycles of pre-roll
  EXPECT_EQ(fit::segment_frames(s), s.data_start + 5u * 2000u);
  EXPECT_EQ(fit::segment_frames(s, 2), s.data_start + 2u * 2000u);
  EXPECT_NEAR(d.mean_speed_rpm(), rpm, 1e-9);
  for (std::size_t c = 0; c < d.cycle_count(); ++c) {
    EXPECT_NEAR(d.cycles[c].duration_s, 0.05, 1e-15);
    EXPECT_NEAR(d.cycles[c].speed_rpm, rpm, 1e-9);
    for (std::size_t w = 0; w < kW; ++w) EXPECT_EQ(d.win_frames[c * kW + w], 250.0) << c << " " << w;
  }
  EXPECT_EQ(d.win_ms.size(), 5u * kW * d.bands);
  EXPECT_EQ(d.cpl_win_ms.size(), 5u * kW * d.bands);
  // The pre-roll is the first cycle repeated.
  for (std::size_t i = 0; i < s.data_start; ++i)
    ASSERT_EQ(s.pressure_pa[i], s.pressure_pa[s.data_start + i % 2000]) << i;
}

TEST(BandDataset, MicrophonesArePairedWithThePressureAcrossTheAcousticDelay) {
  // Microphone = the pressure delayed by 37 frames: paired across the delay, both channels see the same samples.
  fit::ConditionRecording r = sine_recording(50.0, 630.0, 1.0, 1, 3000.0, 4);
  r.delay_frames = 37;
  r.mics_pa.assign(37, 0.0);
  r.mics_pa.insert(r.mics_pa.end(), r.pressure_pa.begin(), r.pressure_pa.end());
  const fit::ConditionData d = build_condition(info("delay", 3000.0), {r});
  ASSERT_EQ(d.cycle_count(), 4u);
  for (std::size_t i = 0; i < d.cpl_ms.size(); ++i) EXPECT_DOUBLE_EQ(d.mic_ms[i], d.cpl_ms[i]) << i;
}

TEST(BandDatasetMake, BandsWithoutACycleHarmonicAreFlaggedAndAPeriodicSignalIsFullyCoherent) {
  // 1500 rpm: cycle frequency 12.5 Hz.
  test_cell::CellCondition c;
  c.rpm = 1500.0;
  c.cycles = 6;
  const fit::BandDataset data = test_cell::block_dataset(preset("linear"), {c});
  const double f0 = 12.5;
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    const dsp::ThirdOctaveBand& band = data.bands[b];
    const double hi = std::min(band.upper_edge_hz, fit::kDatasetRateHz / 2);
    const bool harmonic_inside = std::ceil(band.lower_edge_hz / f0) * f0 < hi;
    EXPECT_EQ(data.band_line_free(0, b), !harmonic_inside) << band.nominal_hz;
  }
  const fit::ConditionData& d = data.conditions[0];
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    const double mid = data.bands[b].exact_mid_hz;
    if (data.band_line_free(0, b) || mid < 50.0 || mid > 12000.0) continue;
    EXPECT_NEAR(d.periodic_share[b], 1.0, 1e-6) << data.bands[b].nominal_hz;
    EXPECT_NEAR(d.coherent_fraction[b], 1.0, 1e-6) << data.bands[b].nominal_hz;
  }
  EXPECT_TRUE(d.info.floor_density.empty());  // a stated floor of 0
}

TEST(BandDataset, BackgroundRunsAreCutIntoBlocksOfACycleAt3000Rpm) {
  fit::ConditionInfo background = info("background", 0.0);
  background.background = true;
  fit::ConditionRecording r = sine_recording(1.0, 1000.0, 1.0, 1, 3000.0, 3);
  for (double& x : r.crank_deg) x = 0.0;  // no crank signal
  const fit::ConditionData d = build_condition(background, {r});
  EXPECT_EQ(d.cycle_count(), 3u);  // 5 blocks of 1600 frames: complete between the wraps into blocks 2 to 5
  EXPECT_NEAR(d.mean_speed_rpm(), 3000.0, 1e-9);
}

TEST(BandDataset, RecordingsThatCannotBeUsedAreErrorsNamingTheCondition) {
  fit::ConditionRecording no_mics = sine_recording(1.0, 1000.0, 1.0, 1, 3000.0, 3);
  no_mics.mic_count = 0;
  no_mics.mics_pa.clear();
  try {
    fit::build_condition(info("quiet", 3000.0), {no_mics});
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("quiet"), std::string::npos) << e.what();
  }
  EXPECT_THROW(fit::build_condition(info("none", 3000.0), {}), std::invalid_argument);
  fit::ConditionRecording short_one = sine_recording(1.0, 1000.0, 1.0, 1, 3000.0, 0);
  EXPECT_THROW(fit::build_condition(info("short", 3000.0), {short_one}), std::invalid_argument);
  fit::ConditionRecording two = sine_recording(1.0, 1000.0, 1.0, 2, 3000.0, 3);
  EXPECT_THROW(fit::build_condition(info("mixed", 3000.0), {sine_recording(1.0, 1000.0, 1.0, 1, 3000.0, 3), two}),
               std::invalid_argument);
}

}  // namespace
}  // namespace noisemon::model
