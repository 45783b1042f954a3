// The baseline stage: the start model tuned on the training conditions and scored on the held-out ones. On data
// whose true block is the model its gap is ~0; a held-out condition whose microphones all read X dB high has the
// thesis gap X (every band), no microphone residual and the crank-window gap X (every window), so the composite
// gap is X sqrt(2) (diagnosis.hpp: sqrt(MS1 + RSS2^2 + MS3)).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "model/diagnosis/stages.hpp"
#include "tests/model/test_diagnosis_data.hpp"

namespace noisemon::model::diagnosis {
namespace {

const std::vector<double> kFlat(4, 0.0);

fit::BandDataset dataset(double heldout_offset_db) {
  const BlockParams truth = preset("linear");
  return fit::make_dataset(
      {testdata::build(testdata::fired("a_1", 3000, 1.0, truth, kFlat, 1)),
       testdata::build(testdata::fired("a_2", 2400, 0.7, truth, kFlat, 2)),
       testdata::build(testdata::fired("b_1", 2700, 0.85, truth, std::vector<double>(4, heldout_offset_db), 3))});
}

struct Baseline {
  DiagnosisOptions opt;
  Context cx;
  Evaluated base;
};

void tune(const fit::BandDataset& data, Baseline& b) {
  b.opt.train = {"a"};
  b.opt.holdout = {"b"};
  b.opt.bootstrap = 20;
  b.cx.data = &data;
  b.cx.opt = &b.opt;
  assign_roles(b.cx);
  mark_bands_and_floors(b.cx, preset("linear"));
  draw_bootstrap(b.cx);
  b.base = tune_baseline(b.cx, preset("linear"), fit::default_free_params(preset("linear")));
}

TEST(Baseline, WhenTheTrueBlockIsTheModelTheGapIsZeroAndTheFitStaysAtTheTruth) {
  const fit::BandDataset data = dataset(0.0);
  Baseline b;
  tune(data, b);
  const ModelScore& s = b.base.score;
  EXPECT_EQ(s.name, "baseline");
  EXPECT_LT(s.heldout_gap_db, 0.05);
  EXPECT_LT(s.heldout_thesis_rms_db, 0.05);
  EXPECT_LT(s.train_rms_db, 0.05);
  const BlockParams truth = preset("linear");
  EXPECT_NEAR(s.model.block.k1 / truth.k1, 1.0, 0.01);
  EXPECT_NEAR(s.model.block.b1 / truth.b1, 1.0, 0.02);
  ASSERT_EQ(s.gaps.size(), 1u);
  int scored = 0;
  for (double g : s.gaps[0])
    if (std::isfinite(g)) {
      ++scored;
      EXPECT_NEAR(g, 0.0, 0.05);
    }
  EXPECT_GT(scored, 20);
}

TEST(Baseline, AKnownOffsetOnTheHeldOutConditionIsItsGap) {
  constexpr double x = 1.0;
  const fit::BandDataset data = dataset(x);
  Baseline b;
  tune(data, b);
  const ModelScore& s = b.base.score;
  EXPECT_LT(s.train_rms_db, 0.05);  // the training conditions are exact: the fit is the truth's
  EXPECT_NEAR(s.heldout_thesis_rms_db, x, 0.05);
  EXPECT_NEAR(s.part_band_ms, x * x, 0.1);
  EXPECT_NEAR(s.part_mic, 0.0, 1e-9);
  EXPECT_NEAR(s.part_window_ms, x * x, 0.1);
  EXPECT_NEAR(s.heldout_gap_db, x * std::sqrt(2.0), 0.05);
  for (double g : s.gaps[0])
    if (std::isfinite(g)) {
      EXPECT_NEAR(g, x, 0.05);
    }
  // Every cycle is the same (but for the bank's slowest bands still settling), so every bootstrap replicate has the
  // same gap: no noise.
  ASSERT_EQ(s.replicate_gaps.size(), 20u);
  EXPECT_NEAR(bootstrap_noise_db(s), 0.0, 1e-3);
  for (double r : s.replicate_gaps) EXPECT_NEAR(r, s.heldout_gap_db, 1e-3);
}

TEST(Baseline, LeaveOneOutScoresEachConditionWithAFoldThatNeverSawIt) {
  // Only b_1 is off (+1 dB at every microphone): its fold is tuned on the exact a_1 and a_2 alone, so its gap is
  // the whole offset in every band (a fold that saw b_1 would have moved towards it).
  constexpr double x = 1.0;
  const fit::BandDataset data = dataset(x);
  Baseline b;
  b.opt.bootstrap = 20;
  b.cx.data = &data;
  b.cx.opt = &b.opt;
  assign_roles(b.cx);
  ASSERT_TRUE(b.cx.loo);
  ASSERT_EQ(b.cx.heldout, (std::vector<std::size_t>{0, 1, 2}));
  mark_bands_and_floors(b.cx, preset("linear"));
  draw_bootstrap(b.cx);
  b.base = tune_baseline(b.cx, preset("linear"), fit::default_free_params(preset("linear")));
  ASSERT_EQ(b.base.score.fold_models.size(), 3u);
  int scored = 0;
  for (double g : b.base.score.gaps[2])
    if (std::isfinite(g)) {
      ++scored;
      EXPECT_NEAR(g, x, 0.1);
    }
  EXPECT_GT(scored, 20);
}

TEST(Baseline, TheBootstrapNoiseIsTheReplicatesSampleStandardDeviation) {
  ModelScore m;
  m.replicate_gaps = {1.0, 2.0, 3.0, 4.0};
  EXPECT_NEAR(bootstrap_noise_db(m), std::sqrt(5.0 / 3.0), 1e-12);
  m.replicate_gaps = {2.5};
  EXPECT_EQ(bootstrap_noise_db(m), 0.0);
  m.replicate_gaps.clear();
  EXPECT_EQ(bootstrap_noise_db(m), 0.0);
}

}  // namespace
}  // namespace noisemon::model::diagnosis
