// The held-out gap of one condition (score_condition and its parts) and the bootstrap draws over cycles, on
// hand-made band powers whose gap is known in closed form.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr std::size_t kGapBands = 6;
constexpr std::size_t kGapMics = 5;

// A condition of `cycles` cycles whose microphones all read `level(c, b)` (mean square), per window an equal share.
template <class Level>
fit::ConditionData condition(std::size_t cycles, Level level) {
  fit::ConditionData d;
  d.bands = kGapBands;
  d.mics = kGapMics;
  d.cycles.resize(cycles, fit::CycleInfo{0.04, 3000.0});
  d.mic_ms.resize(cycles * kGapMics * kGapBands);
  d.win_ms.resize(cycles * kW * kGapBands);
  for (std::size_t c = 0; c < cycles; ++c)
    for (std::size_t b = 0; b < kGapBands; ++b) {
      for (std::size_t m = 0; m < kGapMics; ++m) d.mic_ms[(c * kGapMics + m) * kGapBands + b] = level(c, b);
      for (std::size_t w = 0; w < kW; ++w) d.win_ms[(c * kW + w) * kGapBands + b] = level(c, b) / kW;
    }
  return d;
}

// A prediction of the measured condition lower by `gap_db` in every band, cycle and window.
fit::ConditionPrediction lower_by(const fit::ConditionData& d, double gap_db) {
  const Measured ms = measured_side(d, fit::ExtendedModel{});
  fit::ConditionPrediction p;
  const double f = std::pow(10.0, -gap_db / 10.0);
  for (double x : ms.meas) p.cycle_ms.push_back(x * f);
  for (double x : ms.win) p.win_ms.push_back(x * f);
  return p;
}

const std::vector<char> kAll(kGapBands, 1);
const std::vector<double> kNoFloor(kGapBands, 0.0);

TEST(ScoreCondition, AUniformGapIsTheBandAndTheWindowPartAndNoMicrophoneStandsOut) {
  const fit::ConditionData d = condition(8, [](std::size_t, std::size_t b) { return 1e-3 * (b + 1); });
  const Measured ms = measured_side(d, fit::ExtendedModel{});
  for (double g : {-2.0, 0.5, 3.0}) {
    ScoreDetail det;
    const Parts p = score_condition(d, ms, lower_by(d, g), kAll, kAll, kNoFloor, nullptr, &det);
    EXPECT_NEAR(p.band_ms, g * g, 1e-9);
    EXPECT_NEAR(p.window_ms, g * g, 1e-9);
    EXPECT_NEAR(p.mic, 0.0, 1e-12);
    for (double x : det.gaps) EXPECT_NEAR(x, g, 1e-9);
    for (double x : det.window) EXPECT_NEAR(x, g, 1e-9);
  }
}

TEST(ScoreCondition, OnlyScoredBandsCountAndOnlyFastBandsHaveWindows) {
  fit::ConditionData d = condition(4, [](std::size_t, std::size_t) { return 1e-3; });
  // Band 0 reads 3 dB more than the rest; the prediction is the rest's level everywhere.
  for (std::size_t c = 0; c < 4; ++c)
    for (std::size_t m = 0; m < kGapMics; ++m) d.mic_ms[(c * kGapMics + m) * kGapBands] *= std::pow(10.0, 0.3);
  const Measured ms = measured_side(d, fit::ExtendedModel{});
  fit::ConditionPrediction p = lower_by(condition(4, [](std::size_t, std::size_t) { return 1e-3; }), 0.0);
  std::vector<char> scored(kGapBands, 1), fast(kGapBands, 0);
  scored[0] = 0;
  ScoreDetail det;
  Parts parts = score_condition(d, ms, p, scored, fast, kNoFloor, nullptr, &det);
  EXPECT_NEAR(parts.band_ms, 0.0, 1e-12);
  EXPECT_TRUE(std::isnan(det.gaps[0]));
  EXPECT_EQ(parts.window_ms, 0.0);
  scored[0] = 1;
  parts = score_condition(d, ms, p, scored, fast, kNoFloor, nullptr, &det);
  EXPECT_NEAR(parts.band_ms, 9.0 / kGapBands, 1e-9);  // (3 dB)^2 over six bands
}

TEST(ScoreCondition, AnUpperBoundPredictionCountsOnlyTheSoundAboveIt) {
  const fit::ConditionData d = condition(8, [](std::size_t, std::size_t) { return 2e-3; });
  const Measured ms = measured_side(d, fit::ExtendedModel{});
  for (double g : {-4.0, 2.0}) {
    fit::ConditionPrediction p = lower_by(d, g);
    p.upper.assign(kGapBands, 1);
    p.upper_win.assign(kGapBands * kW, 1);
    const Parts parts = score_condition(d, ms, p, kAll, kAll, kNoFloor, nullptr, nullptr);
    const double counted = g > 0 ? g : 0.0;
    EXPECT_NEAR(parts.band_ms, counted * counted, 1e-9) << g;
    EXPECT_NEAR(parts.window_ms, counted * counted, 1e-9) << g;
  }
}

TEST(ScoreCondition, TheStationaryFloorTheModelLeavesIsNotCountedInTheWindows) {
  // Measured = prediction + a stationary floor F per window: no crank-angle-locked gap once F is allowed for.
  const fit::ConditionData d =
      condition(8, [](std::size_t c, std::size_t b) { return 1e-3 * (1 + 0.1 * c) * (b + 1); });
  const Measured ms = measured_side(d, fit::ExtendedModel{});
  const std::vector<double> floor(kGapBands, 2e-5);
  fit::ConditionPrediction p = lower_by(d, 0.0);
  for (std::size_t i = 0; i < p.win_ms.size(); ++i) p.win_ms[i] -= floor[i % kGapBands];
  EXPECT_NEAR(score_condition(d, ms, p, kAll, kAll, floor, nullptr, nullptr).window_ms, 0.0, 1e-9);
  EXPECT_GT(score_condition(d, ms, p, kAll, kAll, kNoFloor, nullptr, nullptr).window_ms, 0.01);
}

TEST(ScoreCondition, AMiscalibratedMicrophoneCountsBeyondThreeTimesTheArraysSpread) {
  // Four microphones agree, one reads X dB high in every band: its offset from the array's median is X, the
  // array's robust spread is at its floor (0.1 dB), so the residual is X - 0.3 dB.
  for (double x : {1.0, 3.0}) {
    fit::ConditionData d = condition(6, [](std::size_t, std::size_t) { return 1e-3; });
    for (std::size_t c = 0; c < 6; ++c)
      for (std::size_t b = 0; b < kGapBands; ++b)
        d.mic_ms[(c * kGapMics + 2) * kGapBands + b] *= std::pow(10.0, x / 10.0);
    const Measured ms = measured_side(d, fit::ExtendedModel{});
    ScoreDetail det;
    const Parts p = score_condition(d, ms, lower_by(d, 0.0), kAll, kAll, kNoFloor, nullptr, &det);
    EXPECT_NEAR(p.mic, (x - 0.3) * (x - 0.3), 1e-9);
    EXPECT_NEAR(det.mic_resid[2], x - 0.3, 1e-9);
    EXPECT_EQ(det.mic_resid[0], 0.0);
    // The model's gains correct the measurement: with the channel's gain known, nothing stands out.
    fit::ExtendedModel gains;
    gains.on.mic_gain = true;
    gains.ext.mic_gain_db.assign(kGapMics, 0.0);
    gains.ext.mic_gain_db[2] = x;
    const Measured corrected = measured_side(d, gains);
    const fit::ConditionPrediction flat = lower_by(condition(6, [](std::size_t, std::size_t) { return 1e-3; }), 0.0);
    EXPECT_NEAR(score_condition(d, corrected, flat, kAll, kAll, kNoFloor, nullptr, nullptr).mic, 0.0, 1e-12);
  }
}

TEST(ScoreCondition, CycleWeightsEqualTheCyclesRepeated) {
  // A second method for the bootstrap's weights: a condition whose cycles are physically repeated.
  std::mt19937_64 rng(5);
  std::lognormal_distribution<double> scatter(0.0, 0.3);
  std::vector<double> level(5 * kGapBands);
  for (double& x : level) x = 1e-3 * scatter(rng);
  const fit::ConditionData d = condition(5, [&](std::size_t c, std::size_t b) { return level[c * kGapBands + b]; });
  const std::vector<int> counts{2, 0, 1, 0, 2};
  std::vector<std::size_t> repeated;
  for (std::size_t c = 0; c < counts.size(); ++c)
    for (int i = 0; i < counts[c]; ++i) repeated.push_back(c);
  const fit::ConditionData r =
      condition(repeated.size(), [&](std::size_t c, std::size_t b) { return level[repeated[c] * kGapBands + b]; });
  // The same prediction per cycle in both (a fixed shape, 1 dB low).
  const auto shape = [](std::size_t, std::size_t b) { return 1e-3 * (b + 1); };
  const fit::ConditionPrediction pd = lower_by(condition(5, shape), 1.0);
  const fit::ConditionPrediction pr = lower_by(condition(repeated.size(), shape), 1.0);
  const std::vector<double> floor(kGapBands, 1e-6);
  const Parts weighted =
      score_condition(d, measured_side(d, fit::ExtendedModel{}), pd, kAll, kAll, floor, &counts, nullptr);
  const Parts copies =
      score_condition(r, measured_side(r, fit::ExtendedModel{}), pr, kAll, kAll, floor, nullptr, nullptr);
  EXPECT_NEAR(weighted.band_ms, copies.band_ms, 1e-9);
  EXPECT_NEAR(weighted.window_ms, copies.window_ms, 1e-9);
  EXPECT_NEAR(weighted.mic, copies.mic, 1e-9);
}

TEST(ScoreCondition, TheCycleScatterDoesNotCountAsGapOnAverage) {
  // Measured = prediction * 10^(g/10) * a per-cycle lognormal scatter of mean 1: the corrected squared band gap is
  // g^2 on average over many draws, the uncorrected one is larger by the sampling variance.
  constexpr double g = 0.5;
  constexpr std::size_t cycles = 16;
  std::mt19937_64 rng(9);
  const double s = 0.25;  // ln-scale scatter per cycle
  std::normal_distribution<double> z(-0.5 * s * s, s);
  const fit::ConditionData shape = condition(cycles, [](std::size_t, std::size_t) { return 1e-3; });
  const fit::ConditionPrediction p = lower_by(shape, 0.0);
  double corrected = 0.0, raw = 0.0;
  constexpr int draws = 1000;
  for (int i = 0; i < draws; ++i) {
    std::vector<double> f(cycles * kGapBands);
    for (double& x : f) x = std::exp(z(rng)) * std::pow(10.0, g / 10.0);
    const fit::ConditionData d =
        condition(cycles, [&](std::size_t c, std::size_t b) { return 1e-3 * f[c * kGapBands + b]; });
    ScoreDetail det;
    corrected +=
        score_condition(d, measured_side(d, fit::ExtendedModel{}), p, kAll, kAll, kNoFloor, nullptr, &det).band_ms;
    for (double x : det.gaps) raw += x * x / kGapBands;
  }
  corrected /= draws;
  raw /= draws;
  // Variance of the cycle mean's gap: (10 / ln 10)^2 (e^{s^2} - 1) / cycles = 0.076 dB^2.
  const double variance = std::pow(10.0 / std::log(10.0), 2) * std::expm1(s * s) / cycles;
  EXPECT_NEAR(raw - g * g, variance, 0.025);
  EXPECT_NEAR(corrected, g * g, 0.025);
}

TEST(DrawBootstrap, EachReplicateDrawsEveryHeldOutConditionsCyclesWithReplacementTheSameForASeed) {
  fit::BandDataset data;
  data.conditions.push_back(condition(7, [](std::size_t, std::size_t) { return 1.0; }));
  data.conditions.push_back(condition(12, [](std::size_t, std::size_t) { return 1.0; }));
  DiagnosisOptions opt;
  opt.bootstrap = 2000;
  Context cx;
  cx.data = &data;
  cx.opt = &opt;
  cx.heldout = {0, 1};
  draw_bootstrap(cx);
  ASSERT_EQ(cx.counts.size(), 2000u);
  std::vector<double> mean(12, 0.0);
  for (const auto& rep : cx.counts) {
    ASSERT_EQ(rep.size(), 2u);
    ASSERT_EQ(rep[0].size(), 7u);
    ASSERT_EQ(rep[1].size(), 12u);
    int total = 0;
    for (std::size_t c = 0; c < 12; ++c) {
      total += rep[1][c];
      mean[c] += rep[1][c] / 2000.0;
    }
    EXPECT_EQ(total, 12);
  }
  // Multinomial(12, 1/12): every cycle is drawn once per replicate on average (sd of the mean 0.021).
  for (double m : mean) EXPECT_NEAR(m, 1.0, 0.1);
  Context again = cx;
  again.counts.clear();
  draw_bootstrap(again);
  EXPECT_EQ(again.counts, cx.counts);
  opt.seed = 2;
  again.counts.clear();
  draw_bootstrap(again);
  EXPECT_NE(again.counts, cx.counts);
}

}  // namespace
}  // namespace noisemon::model::diagnosis
