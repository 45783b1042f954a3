// The first stage of the diagnosis: roles of the conditions (assign_roles, condition_matches) and the cells at a
// floor (mark_bands_and_floors), on datasets whose roles and floors are known by construction.
#include <fnmatch.h>
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "model/diagnosis/stages.hpp"
#include "tests/model/test_diagnosis_data.hpp"

namespace noisemon::model::diagnosis {
namespace {

using testdata::Recipe;

fit::BandDataset named_conditions() {
  fit::BandDataset d;
  auto add = [&](const std::string& name, bool motored = false, bool background = false) {
    fit::ConditionData c;
    c.info.name = name;
    c.info.motored = motored;
    c.info.background = background;
    d.conditions.push_back(c);
  };
  add("idle_mi12");
  add("idle_mi18");
  add("full_mi12");
  add("full_mi18");
  add("motored_idle", true);
  add("background", false, true);
  return d;
}

Context roles(const fit::BandDataset& data, const DiagnosisOptions& opt) {
  Context cx;
  cx.data = &data;
  cx.opt = &opt;
  assign_roles(cx);
  return cx;
}

using Idx = std::vector<std::size_t>;

TEST(AssignRoles, LeaveOneOutTrainsOnAndScoresEveryFiredConditionMotoredAreReferencesEngineOffIsAFloor) {
  const fit::BandDataset data = named_conditions();
  const DiagnosisOptions opt;
  const Context cx = roles(data, opt);
  EXPECT_TRUE(cx.loo);
  EXPECT_EQ(cx.fired, (Idx{0, 1, 2, 3}));
  EXPECT_EQ(cx.train_fired, (Idx{0, 1, 2, 3}));
  EXPECT_EQ(cx.heldout, (Idx{0, 1, 2, 3}));
  EXPECT_EQ(cx.refs, (Idx{4}));
  EXPECT_EQ(cx.backgrounds, (Idx{5}));
}

// Conditions at these speeds (info.speed_rpm: no cycles, so the stated speed is the mean), one motored run.
fit::BandDataset at_speeds(const std::vector<double>& rpm) {
  fit::BandDataset d;
  for (std::size_t k = 0; k < rpm.size(); ++k) {
    fit::ConditionData c;
    c.info.name = "fired_" + std::to_string(k);
    c.info.speed_rpm = rpm[k];
    d.conditions.push_back(c);
  }
  fit::ConditionData m;
  m.info.name = "motored";
  m.info.motored = true;
  m.info.speed_rpm = rpm.front();
  d.conditions.push_back(m);
  return d;
}

TEST(AssignRoles, LeaveOneGroupOutGroupsTheHeldOutConditionsByOperatingSpeed) {
  const DiagnosisOptions opt;
  // The thesis's two groups (idle at 3050 rpm, full load at 3450), listed interleaved; 3100 rpm is within 5 % of
  // idle.
  const fit::BandDataset thesis = at_speeds({3450, 3050, 3450, 3100, 3050});
  const Context cx = roles(thesis, opt);
  EXPECT_EQ(cx.groups, (std::vector<Idx>{{1, 3, 4}, {0, 2}}));  // indices into heldout, slowest group first
  // Every speed its own condition: the groups would be the condition folds, so there are none.
  EXPECT_TRUE(roles(at_speeds({1500, 1800, 2000, 2600}), opt).groups.empty());
  // One speed for every condition: nothing would be left to train on.
  EXPECT_TRUE(roles(at_speeds({2000, 2010, 2020}), opt).groups.empty());
  // A given split has no folds of its own.
  DiagnosisOptions split;
  split.holdout = {"fired_0"};
  EXPECT_TRUE(roles(thesis, split).groups.empty());
}

TEST(AssignRoles, TheThesisProtocolTrainsAtIdleAndHoldsOutFullLoad) {
  const fit::BandDataset data = named_conditions();
  DiagnosisOptions opt;
  opt.train = {"idle"};
  opt.holdout = {"full"};
  const Context cx = roles(data, opt);
  EXPECT_FALSE(cx.loo);
  EXPECT_EQ(cx.train_fired, (Idx{0, 1}));
  EXPECT_EQ(cx.heldout, (Idx{2, 3}));
  EXPECT_EQ(cx.refs, (Idx{4}));
}

TEST(AssignRoles, WithOnlyAHoldOutEveryOtherFiredConditionTrains) {
  const fit::BandDataset data = named_conditions();
  DiagnosisOptions opt;
  opt.holdout = {"*_mi18"};
  const Context cx = roles(data, opt);
  EXPECT_EQ(cx.train_fired, (Idx{0, 2}));
  EXPECT_EQ(cx.heldout, (Idx{1, 3}));
}

TEST(AssignRoles, ImpossibleSplitsAreErrors) {
  const fit::BandDataset data = named_conditions();
  DiagnosisOptions unknown;
  unknown.train = {"part_load"};
  EXPECT_THROW(roles(data, unknown), std::invalid_argument);
  DiagnosisOptions all_held;
  all_held.holdout = {"idle", "full"};
  EXPECT_THROW(roles(data, all_held), std::invalid_argument);  // nothing left to train on
  DiagnosisOptions same;  // held out wins: idle is not trained on, so nothing trains
  same.train = {"idle"};
  same.holdout = {"idle"};
  EXPECT_THROW(roles(data, same), std::invalid_argument);
  fit::BandDataset one = named_conditions();
  one.conditions.erase(one.conditions.begin() + 1, one.conditions.begin() + 4);  // idle_mi12 the only fired one
  EXPECT_THROW(roles(one, DiagnosisOptions{}), std::invalid_argument);           // leave-one-out needs two
}

TEST(ConditionMatches, GlobsAgreeWithFnmatchAndAPlainPatternIsANameOrAPrefixBeforeAnUnderscore) {
  const std::vector<std::string> names{"idle_mi12", "idle_mi18", "full_mi12", "motored_idle", "idle2_x", "idle"};
  for (const std::string pattern : {"*_mi18", "idle*", "*", "*idle*", "f*_mi1?", "*_*_*", "i*e_m*2", "**mi12"})
    for (const std::string& name : names)
      EXPECT_EQ(condition_matches(pattern, name), fnmatch(pattern.c_str(), name.c_str(), 0) == 0)
          << pattern << " vs " << name;
  EXPECT_TRUE(condition_matches("idle", "idle_mi12"));
  EXPECT_TRUE(condition_matches("idle", "idle"));
  EXPECT_TRUE(condition_matches("idle_mi12", "idle_mi12"));
  EXPECT_FALSE(condition_matches("idle", "idle2_x"));
  EXPECT_FALSE(condition_matches("idl", "idle_mi12"));
  EXPECT_FALSE(condition_matches("mi12", "idle_mi12"));
}

// ------------------------------------------------------------------------------------------- floors

constexpr double kRolesRpm = 3000.0;
constexpr std::size_t kRolesMics = 2;

// A run at kRolesRpm whose microphones hear only `noise` times a gain (dB) and whose pressure is `pressure_cycle`.
Recipe noise_run(const std::string& name, const std::vector<double>& pressure_cycle,
                 const std::vector<std::vector<double>>& noise, double gain_db) {
  Recipe r;
  r.info = testdata::ideal_info(name, kRolesRpm);
  r.pressure_cycle = pressure_cycle;
  for (const auto& w : noise) {
    r.mic_cycles.emplace_back(pressure_cycle.size(), 0.0);
    std::vector<double> x = w;
    for (double& v : x) v *= std::pow(10.0, gain_db / 20.0);
    r.mic_extra.push_back(std::move(x));
  }
  return r;
}

std::vector<std::vector<double>> mic_noise(std::size_t frames, double sigma, std::uint64_t seed) {
  std::vector<std::vector<double>> w;
  for (std::size_t m = 0; m < kRolesMics; ++m) w.push_back(testdata::white_noise(frames, sigma, seed + m));
  return w;
}

Context marked(const fit::BandDataset& data, const DiagnosisOptions& opt) {
  Context cx = roles(data, opt);
  mark_bands_and_floors(cx, preset("linear"));
  return cx;
}

// A band carries information: not cut by the Nyquist frequency, a harmonic of the cycle in it, some sound.
bool informative(const fit::BandDataset& data, std::size_t k, std::size_t b) {
  double m = 0.0;
  for (std::size_t c = 0; c < data.conditions[k].cycle_count(); ++c) m += data.conditions[k].mic_avg_ms(c, b);
  return !data.bands[b].nyquist_cut && !data.band_line_free(k, b) && m > 0;
}

TEST(MarkBandsAndFloors, MicrophonesWithinTheMarginOfTheBackgroundRunsAreFloorLimitedAndNeverScored) {
  const std::vector<double> engine = testdata::pressure_cycle(kRolesRpm, 1.0, 7);
  const std::vector<double> ambient(engine.size(), 1e5);
  Recipe probe;
  probe.pressure_cycle = engine;
  const auto noise = mic_noise(testdata::recording_frames(probe), 0.05, 11);
  // The same noise, scaled and cut into the same cycles: every band's level is exactly the gain above the
  // background run's.
  Recipe loud = noise_run("loud_1", engine, noise, 10.0), quiet = noise_run("quiet_1", engine, noise, 3.0);
  Recipe bg = noise_run("background", ambient, noise, 0.0);
  bg.info.background = true;
  loud.half_cycle_lead_in = quiet.half_cycle_lead_in = bg.half_cycle_lead_in = false;
  const fit::BandDataset data = fit::make_dataset({testdata::build(loud), testdata::build(quiet), testdata::build(bg)});
  ASSERT_EQ(data.conditions[1].cycle_count(), data.conditions[2].cycle_count());
  const DiagnosisOptions opt;  // 6 dB margin
  const Context cx = marked(data, opt);
  int informative_bands = 0;
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    informative_bands += informative(data, 0, b);
    EXPECT_FALSE(cx.floor_limited[0][b]) << b;
    EXPECT_EQ(cx.base_mask[0][b], informative(data, 0, b)) << b;
    EXPECT_EQ(cx.floor_limited[1][b], informative(data, 1, b)) << b;
    EXPECT_FALSE(cx.base_mask[1][b]) << b;
    EXPECT_FALSE(cx.tune_mask[1][b]) << b;
    EXPECT_GT(cx.background_ms[b], 0.0);
  }
  EXPECT_GT(informative_bands, 20);
  // Notes: the Nyquist-cut band and the line-free low bands (below the cycle frequency, 25 Hz: the 20 Hz band).
  EXPECT_EQ(cx.band_notes.back(), "nyquist_cut");
  EXPECT_EQ(cx.band_notes.front(), "line_free");
}

TEST(MarkBandsAndFloors, APressureWithinTheMarginOfTheStatedChainFloorIsFloorLimited) {
  // Pressure: the ambient plus white noise of sigma on the 40 kHz grid; the chain's floor stated as sigma (the same
  // density, 2 sigma^2 / 40 kHz) or 20 dB below it.
  const double sigma = 500.0;
  const std::vector<double> ambient(static_cast<std::size_t>(testdata::kFs * 120.0 / kRolesRpm), 1e5);
  Recipe probe;
  probe.pressure_cycle = ambient;
  const std::size_t frames = testdata::recording_frames(probe);
  const auto noise = mic_noise(frames, 0.5, 21);
  Recipe at_floor = noise_run("at_1", ambient, noise, 0.0), above = noise_run("above_1", ambient, noise, 0.0);
  at_floor.pressure_extra = testdata::white_noise(frames, sigma, 31);
  above.pressure_extra = at_floor.pressure_extra;
  at_floor.info.pressure_floor_pa = sigma;
  above.info.pressure_floor_pa = sigma / 10.0;
  const fit::BandDataset data = fit::make_dataset({testdata::build(at_floor), testdata::build(above)});
  const DiagnosisOptions opt;
  const Context cx = marked(data, opt);
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    EXPECT_EQ(cx.floor_limited[0][b], informative(data, 0, b)) << data.bands[b].nominal_hz;
    EXPECT_FALSE(cx.base_mask[0][b]) << b;
    EXPECT_FALSE(cx.floor_limited[1][b]) << data.bands[b].nominal_hz;
    EXPECT_EQ(cx.base_mask[1][b], informative(data, 1, b)) << b;
  }
  EXPECT_TRUE(cx.pressure_floors[0].stated);
}

TEST(MarkBandsAndFloors, BandsWithinTheMarginOfTheNearestMotoredRunsExcessAreScoredButNotTunedOn) {
  // No sound from the block (constant pressure): each motored run's excess over the start model is its noise.
  // The run at the fired conditions' speed has the same noise as they; the far one (1500 rpm) is 20 dB louder.
  const std::vector<double> ambient(static_cast<std::size_t>(testdata::kFs * 120.0 / kRolesRpm), 1e5);
  const std::vector<double> ambient_slow(2 * ambient.size(), 1e5);
  Recipe probe, probe_slow;
  probe.pressure_cycle = ambient;
  probe_slow.pressure_cycle = ambient_slow;
  const auto noise = mic_noise(testdata::recording_frames(probe), 0.05, 41);
  const auto noise_slow = mic_noise(testdata::recording_frames(probe_slow), 0.5, 51);
  Recipe near = noise_run("motored_near", ambient, noise, 0.0);
  Recipe far = noise_run("motored_far", ambient_slow, noise_slow, 0.0);
  far.info.speed_rpm = kRolesRpm / 2;
  near.info.motored = far.info.motored = true;
  const fit::BandDataset data = fit::make_dataset({testdata::build(noise_run("clear_1", ambient, noise, 10.0)),
                                                   testdata::build(noise_run("noisy_1", ambient, noise, 3.0)),
                                                   testdata::build(near), testdata::build(far)});
  ASSERT_NEAR(data.conditions[3].mean_speed_rpm(), 1500.0, 1.0);
  const DiagnosisOptions opt;
  const Context cx = marked(data, opt);
  EXPECT_EQ(cx.refs, (Idx{2, 3}));
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    EXPECT_FALSE(cx.noise_dominated[0][b]) << data.bands[b].nominal_hz;  // judged by the near run, not the far one
    EXPECT_EQ(cx.tune_mask[0][b], cx.base_mask[0][b]) << b;
    EXPECT_TRUE(cx.noise_dominated[1][b]) << data.bands[b].nominal_hz;
    EXPECT_FALSE(cx.tune_mask[1][b]) << b;
    EXPECT_EQ(cx.base_mask[1][b], informative(data, 1, b)) << b;  // still scored
  }
}

TEST(MarkBandsAndFloors, NoiseDominanceIsJudgedAgainBeyondTheTunedBlockNotTheStartModel) {
  // Every run hears the block `truth` exactly, 12 dB louder than the start preset: beyond the start model the motored
  // run's whole sound is "excess", so every band is noise-dominated; beyond the tuned block (the truth) none is.
  BlockParams truth = preset("linear");
  truth.c0 *= 4.0;
  truth.c1 *= 4.0;
  const std::vector<double> gains(kRolesMics, 0.0);
  testdata::Recipe motored = testdata::fired("motored", kRolesRpm, 0.9, truth, gains, 3);  // within 6 dB of the fired
  motored.info.motored = true;
  const fit::BandDataset data = fit::make_dataset(
      {testdata::build(testdata::fired("fired_1", kRolesRpm, 1.0, truth, gains, 1)),
       testdata::build(testdata::fired("fired_2", kRolesRpm, 0.95, truth, gains, 2)), testdata::build(motored)});
  const DiagnosisOptions opt;
  Context cx = marked(data, opt);
  int scored = 0, noisy = 0;
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    scored += cx.base_mask[0][b];
    noisy += cx.base_mask[0][b] && cx.noise_dominated[0][b];
  }
  ASSERT_GT(scored, 10);
  EXPECT_EQ(noisy, scored);  // beyond the start model: all of it
  EXPECT_TRUE(remark_noise_dominated(cx, truth));
  for (std::size_t k = 0; k < 3; ++k)
    for (std::size_t b = 0; b < data.band_count(); ++b) {
      if (!cx.base_mask[k][b]) continue;  // not scored (Nyquist-cut, line-free): never tuned on either way
      EXPECT_FALSE(cx.noise_dominated[k][b]) << k << " " << data.bands[b].nominal_hz;
      EXPECT_TRUE(cx.tune_mask[k][b]);
    }
  EXPECT_FALSE(remark_noise_dominated(cx, truth));  // nothing changes a second time
}

}  // namespace
}  // namespace noisemon::model::diagnosis
