// The motored runs' law for additive candidates (model/diagnosis/motored_law.cpp): a combustion-independent source
// the model claims must fit under what the motored run measures. The data: the true block heard exactly, plus white
// noise at the microphones of known level; the models: the true block with a stationary source set by hand (no fit),
// so the answer is known: a source at the noise's true level obeys the law, one 6 dB above it is refuted, and a
// pressure-driven model is not judged by it. The pressure-driven law likewise: a mode the motored run does not hear is
// refuted, the true block is not.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "model/diagnosis/stages.hpp"
#include "tests/model/test_diagnosis_data.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kNoisePa = 0.5;  // rms of the white noise at every microphone, both runs (about 88 dB)

testdata::Recipe with_noise(testdata::Recipe r, std::uint64_t seed) {
  const std::size_t frames = testdata::recording_frames(r);
  for (std::size_t m = 0; m < r.mic_cycles.size(); ++m)
    r.mic_extra.push_back(testdata::white_noise(frames, kNoisePa, seed + m));
  return r;
}

struct MotoredCell {
  fit::BandDataset data;
  DiagnosisOptions opt;
  Context cx;
};

void make_cell(MotoredCell& c) {
  const BlockParams truth = preset("linear");
  const std::vector<double> flat(4, 0.0);
  testdata::Recipe motored = testdata::fired("motored_3000", 3000, 0.3, truth, flat, 11);
  motored.info.motored = true;
  c.data = fit::make_dataset({testdata::build(with_noise(testdata::fired("a_1", 3000, 1.0, truth, flat, 1), 100)),
                              testdata::build(with_noise(testdata::fired("a_2", 2400, 0.7, truth, flat, 2), 200)),
                              testdata::build(with_noise(motored, 300))});
  c.opt.bootstrap = 20;
  c.cx.data = &c.data;
  c.cx.opt = &c.opt;
  assign_roles(c.cx);
  mark_bands_and_floors(c.cx, truth);
}

// The true block with a stationary source of the given mean square in every band (Pa^2 per band, microphone mean).
ModelScore with_source(const fit::BandDataset& data, const std::vector<double>& ms) {
  ModelScore m;
  m.model.block = preset("linear");
  m.model.on.stationary = true;
  m.model.ext.stationary_ms = ms;
  m.model.ext.stationary_ms.resize(data.band_count(), 0.0);
  return m;
}

// The white noise's mean square per band as the motored run's microphones measure it beyond the block's sound.
std::vector<double> noise_per_band(const MotoredCell& c) {
  const std::size_t k = c.cx.refs.front(), nb = c.data.band_count();
  fit::ExtendedModel bare;
  bare.block = preset("linear");
  const fit::ConditionPrediction p = predict_condition(c.data, k, bare, false);
  const fit::ConditionData& d = c.data.conditions[k];
  std::vector<double> out(nb, 0.0);
  for (std::size_t cy = 0; cy < d.cycle_count(); ++cy)
    for (std::size_t b = 0; b < nb; ++b)
      out[b] += std::max(0.0, d.mic_avg_ms(cy, b) - p.cycle_ms[cy * nb + b]) / static_cast<double>(d.cycle_count());
  return out;
}

TEST(MotoredLaw, ASourceAtTheNoisesTrueLevelObeysItAndOneSixDbAboveIsRefuted) {
  MotoredCell c;
  make_cell(c);
  ASSERT_EQ(c.cx.refs.size(), 1u);
  const std::vector<double> noise = noise_per_band(c);
  ModelScore right = with_source(c.data, noise);
  judge_motored_law(c.cx, right);
  std::vector<double> loud = noise;
  for (double& x : loud) x *= std::pow(10.0, 6.0 / 10.0);
  ModelScore wrong = with_source(c.data, loud);
  judge_motored_law(c.cx, wrong);
  std::printf("source at the noise's level: overshoot %.2f dB (%s); 6 dB above it: %.2f dB at %s\n",
              right.motored_overshoot_db, right.motored_overshoot_where.c_str(), wrong.motored_overshoot_db,
              wrong.motored_overshoot_where.c_str());
  EXPECT_TRUE(right.motored_law_checked);
  EXPECT_FALSE(right.refuted);
  EXPECT_LT(right.motored_overshoot_db, 0.5);
  EXPECT_TRUE(wrong.refuted);
  // Where the noise dominates the band, the model with the source is 6 dB louder than the run: 10 lg(4 + 1) - 10 lg 2
  // ~ 4 dB at the least (noise = block), up to 6 dB (noise alone); 3 standard errors of 8 cycles come off.
  EXPECT_GT(wrong.motored_overshoot_db, 2.0);
  EXPECT_LT(wrong.motored_overshoot_db, 6.5);
}

TEST(MotoredLaw, ThePredictionsAdditivePartIsWhatTheSourceAddsToTheBarePrediction) {
  // The law reads the bare prediction as the full one less its additive part: held to a second prediction made
  // without the source.
  MotoredCell c;
  make_cell(c);
  const std::size_t k = c.cx.refs.front(), nb = c.data.band_count();
  ModelScore m = with_source(c.data, noise_per_band(c));
  m.model.on.locked = true;  // and a crank-locked source of 1 Pa^2 in the first window of every band
  m.model.ext.locked_ms.assign(nb * fit::kCrankWindows, 0.0);
  for (std::size_t b = 0; b < nb; ++b) m.model.ext.locked_ms[b * fit::kCrankWindows] = 1.0;
  m.model.ext.speed_ref_rpm = 3000;
  fit::ExtendedModel bare;
  bare.block = preset("linear");
  const fit::ConditionPrediction with = predict_condition(c.data, k, m.model, false),
                                 without = predict_condition(c.data, k, bare, false);
  ASSERT_EQ(with.additive_ms.size(), nb);
  const std::size_t cycles = with.cycle_ms.size() / nb;
  for (std::size_t b = 0; b < nb; ++b) {
    double added = 0.0;
    for (std::size_t cy = 0; cy < cycles; ++cy)
      added += (with.cycle_ms[cy * nb + b] - without.cycle_ms[cy * nb + b]) / static_cast<double>(cycles);
    EXPECT_NEAR(with.additive_ms[b], added, 1e-9 * std::max(1.0, added)) << "band " << b;
    EXPECT_GT(with.additive_ms[b], m.model.ext.stationary_ms[b]);  // the locked source adds its window's share
  }
}

TEST(PressureLaw, AModeTheMotoredRunDoesNotHaveIsRefutedAndTheTrueBlockIsNot) {
  // The motored run hears the true block and the noise: the true block as a "candidate" predicts it as well as the
  // baseline (the same block); a 10 dB mode at 250 Hz, which the run does not hear, predicts it worse where the block
  // dominates what the run hears and is refuted (where the noise dominates, any added sound would seem to explain it:
  // those bands are not judged); an additive model is left to the other law.
  MotoredCell c;
  make_cell(c);
  ModelScore baseline;
  baseline.model.block = preset("linear");
  ModelScore same = baseline;
  judge_pressure_law(c.cx, baseline, same);
  ModelScore mode = baseline;
  mode.model.on.second_mode = true;
  mode.model.ext.mode_db = 10.0;
  mode.model.ext.mode_hz = 250.0;  // where the run hears the block (above 500 Hz: the noise)
  mode.model.ext.mode_q = 5.0;
  judge_pressure_law(c.cx, baseline, mode);
  std::printf("the true block: %.2f dB worse; a 10 dB mode at 250 Hz: %.2f dB worse in %s\n", same.motored_worse_db,
              mode.motored_worse_db, mode.motored_worse_where.c_str());
  EXPECT_TRUE(same.pressure_law_checked);
  EXPECT_LE(same.motored_worse_db, 0.0);  // identical predictions: only the measurement's error comes off
  EXPECT_FALSE(same.refuted);
  EXPECT_TRUE(mode.refuted);
  EXPECT_GT(mode.motored_worse_db, 1.0);
  ModelScore additive = with_source(c.data, noise_per_band(c));
  judge_pressure_law(c.cx, baseline, additive);
  EXPECT_FALSE(additive.pressure_law_checked);
}

TEST(MotoredLaw, OnlyAdditiveModelsAreJudged) {
  MotoredCell c;
  make_cell(c);
  ModelScore mode;
  mode.model.block = preset("linear");
  mode.model.on.second_mode = true;
  mode.model.ext.mode_db = 20.0;  // loud, but pressure-driven: the law is not its
  judge_motored_law(c.cx, mode);
  EXPECT_FALSE(mode.motored_law_checked);
  EXPECT_FALSE(mode.refuted);
  EXPECT_TRUE(std::isnan(mode.motored_overshoot_db));
}

}  // namespace
}  // namespace noisemon::model::diagnosis
