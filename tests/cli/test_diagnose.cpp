// Proof of the band-mode diagnosis on withheld effects (issues 4 and 9): the virtual engine's "true" engine carries an
// effect of the list (docs/diagnosis.md) at a realistic magnitude; the diagnosis is told nothing of it. The independent
// reference is what was injected: the verdict must name it and the held-out gap must shrink by at least 60 %.
// A null dataset gives `none`, an effect the library cannot express gives `unexplained`, two effects at once
// name the stronger first with the other significant. Both thesis conditions (idle 3050 rpm / 0 N m and full load
// 3450 rpm / 20 N m, five injection timings each, plus motored runs) take part: leave-one-condition-out holds out
// each fired condition in turn, and the thesis protocol trains at idle and validates at full load.
//
// Every dataset comes from the realistic test cell (drivers/sim/sim_source.hpp: a 0.02 bar pressure-chain floor, ADC,
// gas ringing, microphone self-noise and directivity) unless a test says otherwise; the floors at 0, 0.02, 0.05 and
// 0.2 bar (the real Yanmar record's) are proven separately. tests/independent holds the family whose data shares no
// code with the virtual engine.
//
// Each dataset: the 12 thesis conditions (10 fired, 2 motored), 16 cycles each, generated in memory exactly as
// `noisemon sim` + `noisemon diagnose` would (cli/sim_dataset); the end-to-end test at the bottom goes through
// the files and the command line.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cli/diagnose_command.hpp"
#include "cli/fit_command.hpp"
#include "cli/import_export.hpp"
#include "cli/sim_command.hpp"
#include "cli/sim_dataset.hpp"
#include "model/diagnosis/diagnosis.hpp"
#include "model/engine/pressure_chain.hpp"
#include "tests/support/required.hpp"
#include "tests/support/unique_temp.hpp"

namespace noisemon::cli {
namespace {

constexpr int kCycles = 16;

// The test cell around the engine: the pressure chain's floor (bar rms per encoder sample; 0: an ideal chain), the
// motored reference runs, an engine-off background run.
struct Cell {
  double floor_bar = 0.02;
  bool motored = true;
  bool background_run = false;
};

model::fit::BandDataset campaign(const std::vector<std::string>& effects, const Cell& cell = {}) {
  cli::SimCampaign c;
  for (const cli::SimCondition& k : cli::thesis_conditions())
    if (cell.motored || !k.motored) c.conditions.push_back(k);
  c.cycles = kCycles;
  c.effects = model::engine::parse_effects(effects);
  if (cell.floor_bar > 0.0)
    c.engine.pressure_chain.noise_bar = cell.floor_bar;
  else
    c.engine.pressure_chain = model::engine::PressureChainConfig::ideal();
  c.background_run = cell.background_run;
  return cli::simulate_band_dataset(c);
}

model::diagnosis::DiagnosisResult run(const model::fit::BandDataset& data,
                                      const model::diagnosis::DiagnosisOptions& opt = {}) {
  return model::diagnosis::diagnose(data, model::preset("linear"), "linear", opt);
}

void print(const std::string& title, const model::diagnosis::DiagnosisResult& r) {
  std::printf(
      "%s: verdict %s%s, held-out gap %.2f -> %.2f dB (%.0f %% closed), thesis metric %.2f -> %.2f dB, %.1f s\n",
      title.c_str(), r.verdict.effect.c_str(), r.verdict.also.empty() ? "" : (" + " + r.verdict.also[0]).c_str(),
      r.verdict.heldout_rms_before_db, r.verdict.heldout_rms_after_db, 100 * r.verdict.gap_closed_fraction,
      r.verdict.heldout_thesis_before_db, r.verdict.heldout_thesis_after_db, r.seconds);
  for (const auto& c : r.candidates)
    std::printf("    %-18s gap %6.2f dB  closed %5.0f %%  %s\n", c.name.c_str(), c.heldout_gap_db,
                100 * c.gap_closed_fraction, c.significant ? "significant" : "");
}

// ------------------------------------------------------------------------------------------ one effect

struct Withheld {
  const char* name;    // the effect's name: the expected verdict
  const char* effect;  // what the sim injects (magnitude and qualifiers; never shown to the diagnosis)
};

class WithheldEffect : public ::testing::TestWithParam<Withheld> {};

TEST_P(WithheldEffect, VerdictNamesItAndTheHeldOutGapShrinksByAtLeast60Percent) {
  const Withheld w = GetParam();
  const model::fit::BandDataset data = campaign({w.effect});
  const model::diagnosis::DiagnosisResult r = run(data);
  print(w.effect, r);
  EXPECT_EQ(r.verdict.effect, w.name);
  EXPECT_GE(r.verdict.gap_closed_fraction, 0.6);
  ASSERT_FALSE(r.candidates.empty());
  EXPECT_EQ(r.candidates.front().name, w.name);
  EXPECT_TRUE(r.candidates.front().significant);
  EXPECT_TRUE(r.leave_one_out);
  // Every fired condition of both thesis conditions was held out once.
  EXPECT_EQ(r.heldout.size(), 10u);
}

// The catalogue default of each effect (its realistic magnitude) and a second realistic magnitude (and qualifiers),
// so that nothing is tuned to one value, at the realistic floor. (transducer_noise has no second magnitude yet: at
// 0.15 bar on a stated 0.02 the impact extension wins, 72 % closed; an open issue.) (Against this engine, 111 dB(A)
// at 1.75 m, quieter impacts or backgrounds than the catalogue's ranges change no fired band above the pressure floor's
// margin by more than the cycle-to-cycle noise, and `none` is then the right answer: docs/diagnosis.md, known limits.)
INSTANTIATE_TEST_SUITE_P(
    DesignEffects, WithheldEffect,
    ::testing::Values(
        Withheld{"cubic_damping", "cubic_damping"}, Withheld{"cubic_damping", "cubic_damping=2000"},
        Withheld{"cubic_stiffness", "cubic_stiffness"}, Withheld{"cubic_stiffness", "cubic_stiffness=1.5e13"},
        Withheld{"second_mode", "second_mode"}, Withheld{"second_mode", "second_mode=10,hz=800,q=3"},
        Withheld{"mechanical_noise", "mechanical_noise"}, Withheld{"mechanical_noise", "mechanical_noise=80"},
        Withheld{"background_noise", "background_noise"}, Withheld{"background_noise", "background_noise=110"},
        Withheld{"transducer_noise", "transducer_noise"}, Withheld{"mic_gain", "mic_gain"},
        Withheld{"mic_gain", "mic_gain=-4,mic=6"}, Withheld{"speed_dependence", "speed_dependence"},
        Withheld{"speed_dependence", "speed_dependence=-6"}),
    [](const ::testing::TestParamInfo<Withheld>& info) {
      std::string n = info.param.effect;
      for (char& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return n;
    });

// At the real Yanmar record's floor (0.2 bar rms per encoder sample, ten times the realistic default) every effect
// still above that floor is named. Not here, and why: transducer_noise (its realistic 0.05 bar on top of 0.2 raises the
// floor by 0.3 dB, within the floor's own estimate), mechanical_noise and background_noise (the bands where they
// would show are floor-limited: the pressure there is within 6 dB of the floor, so no prediction is compared).
class WithheldEffectAtTheRealFloor : public ::testing::TestWithParam<Withheld> {};

TEST_P(WithheldEffectAtTheRealFloor, VerdictNamesItAndTheHeldOutGapShrinksByAtLeast60Percent) {
  const Withheld w = GetParam();
  Cell cell;
  cell.floor_bar = 0.2;
  const model::diagnosis::DiagnosisResult r = run(campaign({w.effect}, cell));
  print(std::string(w.effect) + " at 0.2 bar", r);
  EXPECT_EQ(r.verdict.effect, w.name);
  EXPECT_GE(r.verdict.gap_closed_fraction, 0.6);
}

INSTANTIATE_TEST_SUITE_P(AboveTheFloor, WithheldEffectAtTheRealFloor,
                         ::testing::Values(Withheld{"cubic_damping", "cubic_damping=2000"},
                                           Withheld{"cubic_stiffness", "cubic_stiffness=1.5e13"},
                                           Withheld{"second_mode", "second_mode"}, Withheld{"mic_gain", "mic_gain"},
                                           Withheld{"speed_dependence", "speed_dependence"}),
                         [](const ::testing::TestParamInfo<Withheld>& info) { return std::string(info.param.name); });

// ------------------------------------------------------------------------------------------ none, unexplained

// The null dataset (the engine is exactly the linear preset) at every floor, with and without the motored runs and
// a background run: `none`. The verdict `none` is decided on the baseline's held-out gap alone, before any candidate
// is weighed, so one candidate is tried (the whole list costs minutes and cannot change a `none`).
struct NullCase {
  Cell cell;
  std::string name;
};

class NullDataset : public ::testing::TestWithParam<NullCase> {};

TEST_P(NullDataset, GivesNone) {
  const NullCase c = GetParam();
  model::diagnosis::DiagnosisOptions opt;
  opt.candidates = {"mic_gain"};
  const model::fit::BandDataset data = campaign({}, c.cell);
  const model::diagnosis::DiagnosisResult r = run(data, opt);
  print("no effect, " + c.name, r);
  EXPECT_EQ(r.verdict.effect, "none");
  EXPECT_LT(r.verdict.heldout_rms_before_db, 0.5);
  EXPECT_EQ(r.verdict.heldout_rms_after_db, r.verdict.heldout_rms_before_db);
  // The floors are in the report: every condition's pressure floor was judged (stated by the sim's run directories
  // when the chain has a floor), and the summary counts the cells at a floor.
  ASSERT_EQ(r.where.pressure_floor_judged_by.size(), data.conditions.size());
  EXPECT_FALSE(r.where.floor_summary.empty());
  EXPECT_EQ(r.where.mic_floor_source, c.cell.background_run ? "background runs" : "quiet crank windows");
}

std::vector<NullCase> null_cases() {
  static const char* names[] = {"floor_0", "floor_0_02", "floor_0_05", "floor_0_2"};
  std::vector<NullCase> out;
  const double floors[] = {0.0, 0.02, 0.05, 0.2};
  for (int f = 0; f < 4; ++f)
    for (int motored = 1; motored >= 0; --motored)
      for (int bg = 0; bg <= 1; ++bg)
        out.push_back({{floors[f], motored == 1, bg == 1},
                       std::string(names[f]) + (motored ? "_motored" : "_fired_only") + (bg ? "_background" : "")});
  return out;
}

INSTANTIATE_TEST_SUITE_P(Floors, NullDataset, ::testing::ValuesIn(null_cases()),
                         [](const ::testing::TestParamInfo<NullCase>& info) { return info.param.name; });

TEST(Diagnose, TheStatedFloorIsTheOneJudgedAndTheEstimateAgreesWithIt) {
  // The sim's run directories state the chain's floor (pressure.noise_floor_bar); the diagnosis also estimates it
  // from the quiet crank windows. Independent reference: the configured 0.05 bar (white, per encoder sample).
  Cell cell;
  cell.floor_bar = 0.05;
  model::diagnosis::DiagnosisOptions opt;
  opt.candidates = {"mic_gain"};
  const model::fit::BandDataset data = campaign({}, cell);
  const model::diagnosis::DiagnosisResult r = run(data, opt);
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    EXPECT_EQ(r.where.pressure_floor_judged_by[k], "stated") << data.conditions[k].info.name;
    EXPECT_NEAR(r.where.pressure_floor_stated_bar[k], 0.05, 0.001);
    // The estimate: the quietest window's level, an upper bound that the ADC step and the quiet strokes' own
    // pressure raise a little, and the minimum over windows lowers a little.
    EXPECT_NEAR(r.where.pressure_floor_estimated_bar[k], 0.05, 0.05 * 0.3) << data.conditions[k].info.name;
  }
  // Motored runs: their fast bands are pure floor above a few kHz.
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    if (data.conditions[k].info.motored) {
      EXPECT_GE(r.where.floor_limited_bands[k], 5) << data.conditions[k].info.name;
    }
  }
}

TEST(Diagnose, AnEffectNoCandidateCanExpressIsUnexplained) {
  // foreign_soi_gain: fired cycles louder by 0.5 dB per degree of injection advance over 18 deg BTDC, on the
  // structural path. No candidate depends on the injection timing, so none may take the credit.
  const model::diagnosis::DiagnosisResult r = run(campaign({"foreign_soi_gain=0.5"}));
  print("foreign_soi_gain=0.5", r);
  EXPECT_EQ(r.verdict.effect, "unexplained");
  EXPECT_GT(r.verdict.heldout_rms_before_db, 0.5);
  // Where: the gap follows the injection timing at the injected 0.5 dB per degree (the baseline's tuned gain
  // takes out the mean, not the slope).
  std::printf("gap vs SOI %.3f dB/deg\n", r.where.soi_slope_db_per_deg);
  EXPECT_NEAR(r.where.soi_slope_db_per_deg, 0.5, 0.1);
}

TEST(Diagnose, TwoEffectsNameTheStrongerFirstAndTheOtherIsSignificant) {
  // second_mode at 10 dB is much the larger gap; a 2 dB miscalibrated microphone the smaller.
  const model::diagnosis::DiagnosisResult r = run(campaign({"second_mode=10", "mic_gain=2,mic=4"}));
  print("second_mode=10 + mic_gain=2", r);
  EXPECT_EQ(r.verdict.effect, "second_mode");
  bool other_significant = false, on_top = false;
  for (const auto& c : r.candidates)
    if (c.name == "mic_gain") {
      other_significant = c.significant;
      on_top = c.significant_on_top;
    }
  EXPECT_TRUE(other_significant);
  EXPECT_TRUE(on_top);  // and significant on top of the second mode, as the verdict's partner
  ASSERT_FALSE(r.verdict.also.empty());
  EXPECT_EQ(r.verdict.also.front(), "mic_gain");
  EXPECT_GE(r.verdict.gap_closed_fraction, 0.6);
}

// ------------------------------------------------------------------------------------------ thesis protocol

TEST(Diagnose, ThesisProtocolTrainsAtIdleAndValidatesAtFullLoad) {
  // The thesis tuned at idle and validated at full load; with an amplitude-dependent damper in the engine the
  // tuned linear model extrapolates badly to the louder full-load cycles, and the cubic damper, fitted at idle
  // only, carries over.
  model::diagnosis::DiagnosisOptions opt;
  opt.train = {"idle"};
  opt.holdout = {"full"};
  const model::fit::BandDataset data = campaign({"cubic_damping"});
  const model::diagnosis::DiagnosisResult r = run(data, opt);
  print("thesis protocol, cubic_damping", r);
  EXPECT_FALSE(r.leave_one_out);
  ASSERT_EQ(r.train.size(), 5u);
  ASSERT_EQ(r.heldout.size(), 5u);
  for (std::size_t k : r.train) EXPECT_EQ(data.conditions[k].info.name.rfind("idle", 0), 0u);
  for (std::size_t k : r.heldout) EXPECT_EQ(data.conditions[k].info.name.rfind("full", 0), 0u);
  EXPECT_EQ(r.verdict.effect, "cubic_damping");
  EXPECT_GE(r.verdict.gap_closed_fraction, 0.6);
  EXPECT_GT(r.baseline.heldout_thesis_rms_db, r.baseline.train_rms_db);  // extrapolation is worse than the fit
}

TEST(Diagnose, ThesisProtocolOnTheThesisNonlinearSpringDamperNamesBothCubicTerms) {
  // The engine's true block is Table 4.1's nl_spring_damper (k3 = 1e13 and b3 = 2000, besides its own k1, b1);
  // the diagnosis starts from the linear preset, tunes it at idle and validates at full load, as the thesis did.
  // Alone, the cubic spring is hidden by the damper (the impact-noise extension even scores a little better than
  // the damper): only the pair started from the close runner-up explains the extrapolation. On an ideal test cell:
  // with the realistic one (floors, gas ringing) the pair closes too little under this protocol
  // (docs/diagnosis.md, known limits).
  cli::SimCampaign c;
  c.conditions = cli::thesis_conditions();
  c.cycles = kCycles;
  c.engine = drivers::sim::with_ideal_cell(c.engine);
  c.true_block = model::preset("nl_spring_damper");
  const model::fit::BandDataset data = cli::simulate_band_dataset(c);
  model::diagnosis::DiagnosisOptions opt;
  opt.train = {"idle"};
  opt.holdout = {"full"};
  const model::diagnosis::DiagnosisResult r = run(data, opt);
  print("thesis protocol, true nl_spring_damper", r);
  EXPECT_EQ(r.verdict.effect, "cubic_damping");
  ASSERT_EQ(r.verdict.also.size(), 1u);
  EXPECT_EQ(r.verdict.also.front(), "cubic_stiffness");
  EXPECT_GE(r.verdict.gap_closed_fraction, 0.6);
}

// ------------------------------------------------------------------------------------------ end to end

TEST(Diagnose, CommandLineWritesTheReportSchemaFromRunDirectories) {
  const std::string dir = test::unique_temp_dir();
  cli::SimOptions so;
  so.conditions = {"all"};
  so.effects = {"background_noise=110"};
  so.cycles = 12;
  so.out_dir = dir + "/runs";
  so.progress = false;
  cli::run_sim(so);

  cli::DiagnoseOptions o;
  o.data = {dir + "/runs"};  // the directory of run directories (its truth.json is not read)
  o.out_dir = dir + "/diag";
  o.progress = false;
  o.bootstrap = 100;
  std::FILE* sink = std::fopen("/dev/null", "w");
  const DiagnoseOutcome out = run_diagnose(o, sink);
  std::fclose(sink);

  std::ifstream f(out.json_path);
  ASSERT_TRUE(f.good());
  const nlohmann::json j = nlohmann::json::parse(f);
  // report.json's fields.
  for (const char* k : {"baseline", "where", "candidates", "verdict"}) EXPECT_TRUE(j.contains(k)) << k;
  for (const char* k : {"model", "train_rms_db", "heldout_rms_db"}) EXPECT_TRUE(j["baseline"].contains(k)) << k;
  for (const char* k : {"bands_hz", "conditions", "mics"}) EXPECT_TRUE(j["where"].contains(k)) << k;
  for (const char* k : {"effect", "heldout_rms_before_db", "heldout_rms_after_db"})
    EXPECT_TRUE(j["verdict"].contains(k)) << k;
  ASSERT_TRUE(j["candidates"].is_array());
  ASSERT_EQ(j["candidates"].size(), 8u);  // every effect of the list (docs/diagnosis.md) was tried
  for (const auto& c : j["candidates"])
    for (const char* k : {"effect", "heldout_rms_db", "gap_closed_fraction", "significant", "params"})
      EXPECT_TRUE(c.contains(k)) << k;
  EXPECT_EQ(j["verdict"]["effect"], "background_noise");
  EXPECT_EQ(j["candidates"][0]["effect"], "background_noise");  // best first
  // Candidates are ranked by their held-out gap... unless a simpler one is not beaten; the verdict's is the first.
  EXPECT_EQ(j["where"]["bands_hz"].size(), 31u);
  EXPECT_EQ(j["where"]["mics"].size(), 10u);
  EXPECT_EQ(j["where"]["conditions"].size(), 12u);
  // The HTML report is beside it and self-contained.
  std::ifstream h(out.html_path);
  const std::string html((std::istreambuf_iterator<char>(h)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("background_noise"), std::string::npos);
  EXPECT_EQ(html.find("http://"), std::string::npos);
  EXPECT_EQ(html.find("https://"), std::string::npos);

  // A second run into the same directory needs --force; nothing is replaced without it.
  o.force = false;
  EXPECT_THROW(
      {
        try {
          cli::run_diagnose(o, nullptr);
        } catch (const std::runtime_error& e) {
          EXPECT_NE(std::string(e.what()).find("already exists; use --force"), std::string::npos) << e.what();
          throw;
        }
      },
      std::runtime_error);
}

// ------------------------------------------------------------------------------------------ real pressure

// Columns 0 (crank angle) and [first, first + count) of a tab-separated cycle table, as a new table.
std::string table_columns(const std::string& text, std::size_t first, std::size_t count) {
  std::string out, line;
  std::istringstream in(text);
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::istringstream ls(line);
    std::string x;
    while (std::getline(ls, x, '\t')) f.push_back(x);
    if (f.size() < first + count) continue;
    out += f[0];
    for (std::size_t c = first; c < first + count; ++c) out += "\t" + f[c];
    out += "\n";
  }
  return out;
}

TEST(Diagnose, RealYanmarPressureDrivesTheDiagnosisWithTheMotoredRunAsReference) {
  // The real Yanmar L100V cycles (60 fired at 18 N m, 60 motored, 1799.9 rpm) drive the virtual engine: the
  // fired record as two conditions (its first and last 30 cycles: held out in turn, never mixed), the motored
  // one as the reference run that carries the combustion-independent noise.
  const std::string shared = std::string(NOISEMON_SHARED_DIR) + "/data/real/";
  std::ifstream fired_in(shared + "yanmar_l100v_fired_18Nm.txt");
  NOISEMON_REQUIRE(fired_in && std::ifstream(shared + "yanmar_l100v_motored.txt"), "the Yanmar tables under " + shared);
  const std::string fired_text((std::istreambuf_iterator<char>(fired_in)), std::istreambuf_iterator<char>());
  const std::string dir = test::unique_temp_dir();
  std::ofstream(dir + "/fired_a.txt") << table_columns(fired_text, 1, 30);
  std::ofstream(dir + "/fired_b.txt") << table_columns(fired_text, 31, 30);

  std::vector<std::string> pressure_dirs;
  auto import = [&](const std::string& table, const std::string& name, bool motored) {
    cli::CycleTableImportOptions io;
    io.table = table;
    io.table_options.speed_rpm = 1799.9;
    io.table_options.condition.name = name;
    io.table_options.condition.motored = motored;
    io.table_options.condition.load_nm = motored ? 0.0 : 18.0;
    io.table_options.condition.soi_deg_btdc = 9.6;
    io.out_log = dir + "/" + name + ".lcmlog";
    io.epoch_utime = 1'700'000'000'000'000;
    io.progress = false;
    cli::run_import_cycle_table(io);
    cli::ExportOptions eo;
    eo.log = io.out_log;
    eo.out_dir = dir + "/pressure/" + name;
    eo.progress = false;
    cli::run_export(eo);
    pressure_dirs.push_back(eo.out_dir);
  };
  import(dir + "/fired_a.txt", "yanmar_fired_a", false);
  import(dir + "/fired_b.txt", "yanmar_fired_b", false);
  import(shared + "yanmar_l100v_motored.txt", "yanmar_motored", true);

  auto diagnose_with = [&](const std::string& set, const std::vector<std::string>& effects) {
    cli::SimOptions so;
    so.pressure_dirs = pressure_dirs;
    so.out_dir = dir + "/" + set;
    so.seed = 5;
    so.progress = false;
    so.effects = effects;
    cli::run_sim(so);
    cli::DiagnoseOptions o;
    o.data = {so.out_dir};
    o.out_dir = dir + "/diag_" + set;
    o.progress = false;
    std::FILE* sink = std::fopen("/dev/null", "w");
    nlohmann::json report = cli::run_diagnose(o, sink).report;
    std::fclose(sink);
    const nlohmann::json& v = report["verdict"];
    std::printf("Yanmar %s: verdict %s, held-out gap %.2f -> %.2f dB; best candidate %s\n", set.c_str(),
                v["effect"].get<std::string>().c_str(), v["heldout_rms_before_db"].get<double>(),
                v["heldout_rms_after_db"].get<double>(), report["candidates"][0]["effect"].get<std::string>().c_str());
    // The two fired halves are trained and held out in turn, the motored run is the reference.
    for (const auto& c : report["where"]["conditions"])
      EXPECT_EQ(c["role"], c["name"] == "yanmar_motored" ? "reference" : "train+heldout") << c["name"];
    return report;
  };
  const nlohmann::json null = diagnose_with("null", {});
  EXPECT_EQ(null["verdict"]["effect"], "none");
  // A structural effect on real combustion pressure.
  const nlohmann::json mode = diagnose_with("mode", {"second_mode=8,hz=1600"});
  EXPECT_EQ(mode["verdict"]["effect"], "second_mode");
  EXPECT_GE(mode["verdict"]["gap_closed_fraction"].get<double>(), 0.6);
  // Loud impacts (90 dB(A) at 3050 rpm, 83 dB(A) at this speed): the real record's pressure noise (+-0.5 bar)
  // drives the model to ~108 dB(A), so the impacts change the fired spectra by a few hundredths of a dB - within
  // the tolerance, as the verdict may say - but with the motored run as the reference, mechanical_noise is still
  // the candidate that explains what there is.
  const nlohmann::json mech = diagnose_with("mech", {"mechanical_noise=90"});
  EXPECT_EQ(mech["candidates"][0]["effect"], "mechanical_noise");
}

TEST(Diagnose, SilverboxFitThenWaveformDiagnosisNamesTheCubicSpringAndBeatsThePublishedBaselines) {
  // The protocol through the commands: `noisemon fit` in waveform mode (linear model) on the real
  // Silverbox training multisines, then `noisemon diagnose` in waveform mode from that parameter file, scoring
  // the benchmark's extrapolating arrow test set. Independent reference: the published free-run RMS errors
  // (data README): LSTM 2.68 mV on the arrow, the best of the published baselines. For time, both fit on
  // 4000-sample chunks of the training record and hold out other chunks of it (never a test set).
  const std::string csv = std::string(NOISEMON_SHARED_DIR) + "/data/real/silverbox_SNLS80mV.csv";
  NOISEMON_REQUIRE(std::ifstream(csv), csv);
  const std::string dir = test::unique_temp_dir();
  std::vector<std::string> train, held;
  for (std::size_t b = 40650; b + 4000 <= 105712; b += 16000)
    train.push_back(std::to_string(b) + ":" + std::to_string(b + 4000));
  for (std::size_t b = 40650 + 8000; b + 4000 <= 105712; b += 16000)
    held.push_back(std::to_string(b) + ":" + std::to_string(b + 4000));
  cli::FitCommandOptions fo;
  fo.data = {csv};
  fo.fs_hz = 1e7 / 16384.0;
  fo.train = train;
  fo.holdout = held;
  fo.out = dir + "/linear.toml";
  fo.progress = false;
  std::FILE* sink = std::fopen("/dev/null", "w");
  const FitCommandResult fit = run_fit(fo, sink);
  std::fclose(sink);
  EXPECT_EQ(fit.mode, "waveform");

  cli::DiagnoseOptions o;
  o.data = {csv};
  o.fs_hz = fo.fs_hz;
  o.model = fo.out;
  o.train = train;
  o.holdout = held;
  o.tests = {"arrow=100:40575"};
  o.max_iterations = 15;
  o.out_dir = dir + "/diag";
  o.progress = false;
  const nlohmann::json r = cli::run_diagnose(o, nullptr).report;
  EXPECT_EQ(r["mode"], "waveform");
  EXPECT_EQ(r["verdict"]["effect"], "cubic_stiffness");
  ASSERT_EQ(r["test_sets"].size(), 1u);
  const double base = r["test_sets"][0]["baseline_rms"].get<double>(),
               best = r["test_sets"][0]["best_rms"].get<double>();
  std::printf("Silverbox arrow (extrapolating): linear %.2f mV, diagnosed model %.3f mV (LSTM 2.68 mV)\n", 1e3 * base,
              1e3 * best);
  EXPECT_LT(best, base / 3.0);
  EXPECT_LT(1e3 * best, 2.68);
}

TEST(Diagnose, BadArgumentsAreErrorsNamingTheOptionOrPath) {
  const std::string dir = test::unique_temp_dir();
  auto error_of = [&](DiagnoseOptions o) {
    o.progress = false;
    if (o.out_dir.empty()) o.out_dir = dir + "/d";
    try {
      cli::run_diagnose(o, nullptr);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  cli::DiagnoseOptions o;
  o.data = {dir + "/nothing_here"};
  EXPECT_NE(error_of(o).find(dir + "/nothing_here: no such file or directory"), std::string::npos);
  std::filesystem::create_directories(dir + "/empty");
  o.data = {dir + "/empty"};
  EXPECT_NE(error_of(o).find("neither a run directory (no run.json) nor a directory of them"), std::string::npos);
  { std::ofstream(dir + "/w.csv") << "1,2\n3,4\n"; }
  o.data = {dir + "/w.csv"};
  EXPECT_NE(error_of(o).find("--fs"), std::string::npos);
  o.data = {dir + "/w.csv", dir + "/empty"};
  EXPECT_NE(error_of(o).find("DATA mixes .csv waveforms and band data: give --mode"), std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir + "/d/report.json"));
}

}  // namespace
}  // namespace noisemon::cli
