// The verdict stage on hand-made scores: `none` within the tolerance or the baseline's bootstrap noise, the best
// significant candidate when it closes at least half the gap or leaves no more than the tolerance, `unexplained`
// otherwise, never a forced name. (Pairs need refits; they are proven end to end in tests/cli/test_diagnose.)
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr std::size_t kVerdictBands = 3;

ModelScore scored(const std::string& name, double gap, double thesis, bool significant = false) {
  ModelScore m;
  m.name = name;
  m.effects = {name};
  m.heldout_gap_db = gap;
  m.heldout_thesis_rms_db = thesis;
  m.significant = significant;
  m.replicate_gaps.assign(50, gap);
  m.gaps = {std::vector<double>(kVerdictBands, gap)};
  return m;
}

struct Case {
  fit::BandDataset data;
  DiagnosisOptions opt;  // tolerance 0.5 dB, half the gap closed
  Context cx;
  CandidateRound round;
  DiagnosisResult res;

  Case(const ModelScore& baseline, const std::vector<ModelScore>& ranked) {
    data.bands.resize(kVerdictBands);
    cx.data = &data;
    cx.opt = &opt;
    res.baseline = baseline;
    for (const ModelScore& s : ranked) {
      round.specs.push_back(spec_for(s.name));
      Evaluated e;
      e.score = s;
      round.evals.push_back(e);
      round.order.push_back(round.order.size());
      res.candidates.push_back(s);
    }
  }
  const Verdict& judged() {
    StageLog log(opt, res);
    judge(cx, round, {}, res, log);
    return res.verdict;
  }
};

TEST(Verdict, NoneWhenTheBaselineAgreesWithinTheTolerance) {
  Case c(scored("baseline", 0.4, 0.3), {scored("second_mode", 0.1, 0.1, true)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "none");
  EXPECT_TRUE(v.also.empty());
  EXPECT_DOUBLE_EQ(v.heldout_rms_before_db, 0.4);
  EXPECT_DOUBLE_EQ(v.heldout_rms_after_db, 0.4);
  EXPECT_DOUBLE_EQ(v.heldout_thesis_after_db, 0.3);
  EXPECT_DOUBLE_EQ(v.gap_closed_fraction, 0.0);
  // The significant candidate is named beside `none`, not as the verdict.
  EXPECT_EQ(v.below_tolerance, "second_mode");
  EXPECT_DOUBLE_EQ(v.below_tolerance_after_db, 0.1);
  EXPECT_NE(v.explanation.find("second_mode closes the gap significantly (0.40 -> 0.10 dB)"), std::string::npos);
}

TEST(Verdict, NothingBelowTheToleranceWhenNoCandidateIsSignificant) {
  Case c(scored("baseline", 0.4, 0.3), {scored("second_mode", 0.3, 0.3, false)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "none");
  EXPECT_TRUE(v.below_tolerance.empty());
  EXPECT_EQ(v.explanation.find("significantly"), std::string::npos);
}

TEST(Verdict, NoneWhenTheGapIsWithinTwiceTheBaselinesBootstrapNoise) {
  ModelScore base = scored("baseline", 1.0, 0.8);
  for (std::size_t i = 0; i < base.replicate_gaps.size(); ++i) base.replicate_gaps[i] = i % 2 ? 0.4 : 1.6;
  Case c(base, {scored("second_mode", 0.1, 0.1, true)});
  const Verdict& v = c.judged();
  EXPECT_NEAR(v.noise_db, 0.6 * std::sqrt(50.0 / 49.0), 1e-12);  // sample standard deviation of +-0.6
  EXPECT_EQ(v.effect, "none");
  EXPECT_TRUE(v.below_tolerance.empty());  // a gap within its noise has no cause to name
}

TEST(Verdict, UnexplainedWhenNoCandidateIsSignificant) {
  Case c(scored("baseline", 2.0, 1.5), {scored("second_mode", 0.5, 0.4, false)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "unexplained");
  EXPECT_DOUBLE_EQ(v.heldout_rms_after_db, 2.0);
  EXPECT_DOUBLE_EQ(v.gap_closed_fraction, 0.0);
}

TEST(Verdict, TheBestSignificantCandidateWhenItClosesAtLeastHalfTheGap) {
  Case c(scored("baseline", 2.0, 1.5), {scored("mic_gain", 0.8, 0.6, true)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "mic_gain");
  EXPECT_TRUE(v.also.empty());
  EXPECT_DOUBLE_EQ(v.heldout_rms_after_db, 0.8);
  EXPECT_DOUBLE_EQ(v.heldout_thesis_after_db, 0.6);
  EXPECT_NEAR(v.gap_closed_fraction, 0.6, 1e-12);
  EXPECT_EQ(v.explanation, "mic_gain closes 60 % of the held-out gap");
  EXPECT_TRUE(c.res.combinations.empty());
}

TEST(Verdict, UnexplainedWhenTheBestClosesLessThanHalfAndLeavesMoreThanTheTolerance) {
  Case c(scored("baseline", 2.0, 1.5), {scored("second_mode", 1.5, 1.2, true)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "unexplained");
  EXPECT_EQ(v.explanation, "a significant gap remains: the best candidate (second_mode) closes only 25 % of it");
  EXPECT_DOUBLE_EQ(v.heldout_rms_after_db, 2.0);
}

TEST(Verdict, NamedWhenWhatTheBestLeavesIsWithinTheToleranceHoweverLittleItClosed) {
  Case c(scored("baseline", 0.6, 0.5), {scored("speed_dependence", 0.45, 0.4, true)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "speed_dependence");
  EXPECT_NEAR(v.gap_closed_fraction, 0.25, 1e-12);
}

TEST(Verdict, TheFirstSignificantInTheRankingIsNamedNotTheSmallestGap) {
  // No pair is tried: the named candidate already leaves less than the tolerance.
  Case c(scored("baseline", 2.0, 1.5),
         {scored("mechanical_noise", 0.3, 0.3, false), scored("second_mode", 0.4, 0.3, true)});
  const Verdict& v = c.judged();
  EXPECT_EQ(v.effect, "second_mode");
  EXPECT_DOUBLE_EQ(v.heldout_rms_after_db, 0.4);
  EXPECT_TRUE(c.res.combinations.empty());
}

TEST(Verdict, PerBandBeforeAndAfterAreTheRmsOverTheHeldOutConditions) {
  ModelScore base = scored("baseline", 2.0, 1.5);
  base.gaps = {{1.0, NAN, 2.0}, {3.0, NAN, -2.0}};
  ModelScore best = scored("second_mode", 0.5, 0.4, true);
  best.gaps = {{0.5, NAN, 0.0}, {0.5, 1.0, 0.0}};
  Case c(base, {best});
  const Verdict& v = c.judged();
  ASSERT_EQ(v.band_before_db.size(), kVerdictBands);
  EXPECT_NEAR(v.band_before_db[0], std::sqrt(5.0), 1e-12);
  EXPECT_TRUE(std::isnan(v.band_before_db[1]));
  EXPECT_NEAR(v.band_before_db[2], 2.0, 1e-12);
  EXPECT_NEAR(v.band_after_db[0], 0.5, 1e-12);
  EXPECT_NEAR(v.band_after_db[1], 1.0, 1e-12);
  EXPECT_NEAR(v.band_after_db[2], 0.0, 1e-12);
}

}  // namespace
}  // namespace noisemon::model::diagnosis
