// The candidates stage: each effect's model extension, the judgement against the baseline (improvement, bootstrap
// significance, the thesis metric must not get worse), the ranking rule, and one candidate found end to end on a
// dataset with a known miscalibrated microphone.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/diagnosis/stages.hpp"
#include "tests/model/test_diagnosis_data.hpp"

namespace noisemon::model::diagnosis {
namespace {

TEST(Candidates, TheEffectsAreDesignMdsListInItsOrder) {
  EXPECT_EQ(candidate_effects(),
            (std::vector<std::string>{"cubic_damping", "cubic_stiffness", "second_mode", "mechanical_noise",
                                      "background_noise", "transducer_noise", "mic_gain", "speed_dependence"}));
}

TEST(Candidates, EachEffectIsItsModelExtensionAndAPairIsTheUnionOfBoth) {
  const CandidateSpec damping = spec_for("cubic_damping"), stiffness = spec_for("cubic_stiffness");
  EXPECT_EQ(damping.extra_free, std::vector<fit::BlockParam>{fit::BlockParam::kB3});
  EXPECT_FALSE(damping.ext.any());
  EXPECT_EQ(stiffness.extra_free, std::vector<fit::BlockParam>{fit::BlockParam::kK3});
  EXPECT_TRUE(spec_for("second_mode").ext.second_mode);
  EXPECT_TRUE(spec_for("mechanical_noise").ext.locked);
  EXPECT_TRUE(spec_for("background_noise").ext.stationary);
  EXPECT_TRUE(spec_for("transducer_noise").ext.transducer);
  EXPECT_TRUE(spec_for("mic_gain").ext.mic_gain);
  EXPECT_TRUE(spec_for("speed_dependence").ext.speed);
  for (const std::string& name : candidate_effects()) {
    const CandidateSpec s = spec_for(name);
    EXPECT_EQ(s.name, name);
    EXPECT_EQ(s.effects, std::vector<std::string>{name});
    // Exactly one thing added: one extension or one free cubic term.
    const fit::ExtensionSet& e = s.ext;
    const int added = e.second_mode + e.speed + e.transducer + e.stationary + e.locked + e.mic_gain +
                      static_cast<int>(s.extra_free.size());
    EXPECT_EQ(added, 1) << name;
  }
  EXPECT_THROW(spec_for("gremlins"), std::invalid_argument);
  const CandidateSpec pair = combine(spec_for("second_mode"), damping);
  EXPECT_EQ(pair.name, "second_mode+cubic_damping");
  EXPECT_EQ(pair.effects, (std::vector<std::string>{"second_mode", "cubic_damping"}));
  EXPECT_TRUE(pair.ext.second_mode);
  EXPECT_EQ(pair.extra_free, std::vector<fit::BlockParam>{fit::BlockParam::kB3});
  const CandidateSpec both = combine(damping, stiffness);
  EXPECT_EQ(both.extra_free, (std::vector<fit::BlockParam>{fit::BlockParam::kB3, fit::BlockParam::kK3}));
  EXPECT_EQ(combine(damping, damping).extra_free, std::vector<fit::BlockParam>{fit::BlockParam::kB3});
}

// A model scored on `cells` held-out band cells, every one off by the gap.
ModelScore scored(double gap, double thesis, std::vector<double> replicates, int parameters = 4, int cells = 200) {
  ModelScore m;
  m.heldout_gap_db = gap;
  m.heldout_thesis_rms_db = thesis;
  m.part_band_ms = thesis * thesis;
  m.replicate_gaps = std::move(replicates);
  m.parameters = parameters;
  m.gaps = {std::vector<double>(static_cast<std::size_t>(cells), gap)};
  set_information_criterion(m);
  return m;
}

std::vector<double> around(double centre, double spread, int n = 100) {
  std::vector<double> r;
  for (int i = 0; i < n; ++i) r.push_back(centre + spread * std::sin(1.0 + i));
  return r;
}

TEST(Candidates, SignificantWhenItBeatsTheBaselineIn95PercentOfTheReplicatesByAtLeastTheMinimum) {
  const ModelScore base = scored(1.2, 1.0, around(1.2, 0.05));
  ModelScore clear = scored(0.4, 0.3, around(0.4, 0.05));
  compare_with(clear, base, 0.1);
  EXPECT_TRUE(clear.significant);
  EXPECT_DOUBLE_EQ(clear.win_fraction, 1.0);
  EXPECT_NEAR(clear.improvement_db, 0.8, 1e-12);
  EXPECT_NEAR(clear.gap_closed_fraction, 1.0 - 0.4 / 1.2, 1e-12);
  EXPECT_NEAR(clear.closes_band_db, 1.0 - 0.3, 1e-12);
  // Better in every replicate but by less than the minimum improvement.
  ModelScore small = scored(1.15, 0.98, around(1.15, 0.05));
  compare_with(small, base, 0.1);
  EXPECT_DOUBLE_EQ(small.win_fraction, 1.0);
  EXPECT_FALSE(small.significant);
  // Better on average, but only in about half of the replicates.
  std::vector<double> scattered = around(1.2, 0.05);
  for (std::size_t i = 0; i < scattered.size(); ++i) scattered[i] += (i % 2 ? -1.0 : 0.6);
  ModelScore noisy = scored(1.0, 0.8, scattered);
  compare_with(noisy, base, 0.1);
  EXPECT_LT(noisy.win_fraction, 0.95);
  EXPECT_FALSE(noisy.significant);
  // Clearly better on the composite gap but worse on the thesis metric by more than 0.05 dB: never significant.
  ModelScore worse = scored(0.4, 1.06, around(0.4, 0.05));
  compare_with(worse, base, 0.1);
  EXPECT_TRUE(worse.thesis_worse);
  EXPECT_FALSE(worse.significant);
  ModelScore slightly = scored(0.4, 1.04, around(0.4, 0.05));
  compare_with(slightly, base, 0.1);
  EXPECT_TRUE(slightly.significant);
}

TEST(Candidates, TheInformationCriterionCountsTheScoredCellsAndChargesEveryFreeLevel) {
  ModelScore m;
  m.heldout_gap_db = 0.5;
  m.parameters = 10;
  m.gaps = {{0.4, kNaN, -0.6}, {0.5, 0.5, kNaN}};  // two held-out conditions: 4 band cells scored
  m.cell_gaps = {{kNaN, 0.2, 0.3}, {0.1, kNaN, kNaN}};
  m.mic_resid = {{0.0, 0.1}, {0.0, 0.0}};
  set_information_criterion(m);
  EXPECT_EQ(m.heldout_cells, 4 + 3 + 4);
  // Gaussian cells of rms 0.5 dB: -2 ln L = n ln(0.25) + const; each parameter costs ln(n).
  EXPECT_NEAR(m.information_criterion, 11 * std::log(0.25) + 10 * std::log(11.0), 1e-9);
}

TEST(Candidates, ACandidateWhoseClosedGapDoesNotPayForItsFreeLevelsIsNotSignificant) {
  const ModelScore base = scored(0.40, 0.40, around(0.40, 0.02), 4);
  // 90 free levels for 10 % of a 0.4 dB gap, better in every replicate: on 200 cells it does not pay for them.
  ModelScore spectrum = scored(0.36, 0.36, around(0.36, 0.02), 90);
  compare_with(spectrum, base, 0.01);
  EXPECT_DOUBLE_EQ(spectrum.win_fraction, 1.0);
  EXPECT_FALSE(spectrum.pays_for_parameters);
  EXPECT_FALSE(spectrum.significant);
  // Closing three quarters of the gap, it does.
  ModelScore strong = scored(0.10, 0.10, around(0.10, 0.02), 90);
  compare_with(strong, base, 0.01);
  EXPECT_TRUE(strong.pays_for_parameters);
  EXPECT_TRUE(strong.significant);
}

TEST(Candidates, BeatsIsTheShareOfReplicatesWithTheSmallerGap) {
  const ModelScore a = scored(1.0, 1.0, {1, 2, 3, 4}), b = scored(1.0, 1.0, {2, 1, 4, 5});
  EXPECT_DOUBLE_EQ(beats(a, b), 0.75);
  EXPECT_DOUBLE_EQ(beats(b, a), 0.25);
  EXPECT_DOUBLE_EQ(beats(scored(0.5, 0, {}), scored(0.6, 0, {})), 1.0);  // no replicates: the gaps decide
}

Evaluated candidate(const std::string& name, double gap, std::vector<double> replicates, int parameters,
                    bool significant) {
  Evaluated e;
  e.score = scored(gap, gap, std::move(replicates), parameters);
  e.score.name = name;
  e.score.significant = significant;
  return e;
}

std::vector<std::string> names(const std::vector<Evaluated>& evals, const std::vector<std::size_t>& order) {
  std::vector<std::string> out;
  for (std::size_t i : order) out.push_back(evals[i].score.name);
  return out;
}

TEST(Candidates, RankedByTheHeldOutGapTheSimplerFirstWhenTheBetterIsNotClearlyBetter) {
  // "complex" has the smaller gap, "simple" fewer parameters; complex beats simple in 60 % of the replicates.
  std::vector<double> simple_r = around(0.40, 0.05), complex_r = simple_r;
  for (std::size_t i = 0; i < complex_r.size(); ++i) complex_r[i] += (i % 5 < 3) ? -0.08 : 0.04;
  std::vector<Evaluated> evals{candidate("worst", 1.0, around(1.0, 0.05), 4, false),
                               candidate("complex", 0.36, complex_r, 8, true),
                               candidate("simple", 0.40, simple_r, 5, true)};
  EXPECT_EQ(names(evals, rank_candidates(evals, 0.1)), (std::vector<std::string>{"simple", "complex", "worst"}));
  // Beating it in every replicate but by less than 0.1 dB is not clearly better either.
  evals[1].score.replicate_gaps = simple_r;
  for (double& r : evals[1].score.replicate_gaps) r -= 0.04;
  EXPECT_EQ(names(evals, rank_candidates(evals, 0.1)), (std::vector<std::string>{"simple", "complex", "worst"}));
  // In every replicate and by 0.2 dB: the better one first.
  evals[1].score.heldout_gap_db = 0.2;
  for (double& r : evals[1].score.replicate_gaps) r -= 0.16;
  EXPECT_EQ(names(evals, rank_candidates(evals, 0.1)), (std::vector<std::string>{"complex", "simple", "worst"}));
  // A simpler candidate that is not significant does not move up.
  evals[1].score.heldout_gap_db = 0.36;
  evals[1].score.replicate_gaps = complex_r;
  evals[2].score.significant = false;
  EXPECT_EQ(names(evals, rank_candidates(evals, 0.1)), (std::vector<std::string>{"complex", "simple", "worst"}));
}

TEST(Candidates, AManyLevelSpectrumDoesNotOutrankAFewParameterModeByFittingTheNoise) {
  // The spectrum's gap is clearly smaller in every replicate, but with 90 parameters against 8 on 200 held-out
  // cells its information criterion is the higher: the mode ranks first.
  std::vector<double> mode_r = around(0.42, 0.02), spectrum_r = around(0.30, 0.02);
  std::vector<Evaluated> evals{candidate("spectrum", 0.30, spectrum_r, 90, true),
                               candidate("mode", 0.42, mode_r, 8, true)};
  EXPECT_EQ(names(evals, rank_candidates(evals, 0.1)), (std::vector<std::string>{"mode", "spectrum"}));
  // The same gaps on 5000 cells: the spectrum's closer fit there is worth its levels.
  for (Evaluated& e : evals) {
    e.score.gaps = {std::vector<double>(5000, e.score.heldout_gap_db)};
    set_information_criterion(e.score);
  }
  EXPECT_EQ(names(evals, rank_candidates(evals, 0.1)), (std::vector<std::string>{"spectrum", "mode"}));
}

TEST(Candidates, AMiscalibratedMicrophoneIsFoundByTheMicGainCandidate) {
  // Microphone 3 of four reads 3 dB high in every condition; the block is the truth. The baseline carries the
  // microphone residual 3 - 0.3 dB (three times the array's floor spread of 0.1 dB); the candidate estimates the
  // gain (3 dB from the others' median) and closes it.
  const BlockParams truth = preset("linear");
  const std::vector<double> gains{0.0, 0.0, 3.0, 0.0};
  const fit::BandDataset data =
      fit::make_dataset({testdata::build(testdata::fired("a_1", 3000, 1.0, truth, gains, 1)),
                         testdata::build(testdata::fired("a_2", 2400, 0.7, truth, gains, 2)),
                         testdata::build(testdata::fired("b_1", 2700, 0.85, truth, gains, 3))});
  DiagnosisOptions opt;
  opt.train = {"a"};
  opt.holdout = {"b"};
  opt.bootstrap = 20;
  opt.candidates = {"mic_gain"};
  Context cx;
  cx.data = &data;
  cx.opt = &opt;
  assign_roles(cx);
  mark_bands_and_floors(cx, truth);
  draw_bootstrap(cx);
  const std::vector<fit::BlockParam> free = fit::default_free_params(truth);
  const Evaluated base = tune_baseline(cx, truth, free);
  EXPECT_NEAR(std::sqrt(base.score.part_mic), 2.7, 0.05);
  DiagnosisResult res;
  StageLog log(opt, res);
  const CandidateRound round = evaluate_candidates(cx, truth, base, free, log);
  ASSERT_EQ(round.evals.size(), 1u);
  const ModelScore& mic = round.evals[0].score;
  EXPECT_EQ(mic.name, "mic_gain");
  ASSERT_EQ(mic.model.ext.mic_gain_db.size(), 4u);
  EXPECT_NEAR(mic.model.ext.mic_gain_db[2], 3.0, 0.05);
  EXPECT_EQ(mic.model.ext.mic_gain_db[0], 0.0);
  EXPECT_NEAR(mic.part_mic, 0.0, 1e-6);
  EXPECT_NEAR(mic.closes_mic_db, 2.7, 0.05);
  EXPECT_TRUE(mic.significant);
  EXPECT_LT(mic.heldout_gap_db, 0.1);
  EXPECT_EQ(mic.parameters, base.score.parameters + 1);  // one microphone's gain
  ASSERT_EQ(res.timing.size(), 1u);
  EXPECT_EQ(res.timing[0].first, "candidate mic_gain");
}

}  // namespace
}  // namespace noisemon::model::diagnosis
