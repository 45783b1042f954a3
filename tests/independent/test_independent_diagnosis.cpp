// Withheld effects on data the project did not make. The independent cell (cell_synth.hpp: the real Yanmar pressure
// records with their real chain noise, eq. 4.1 synthesised in the frequency domain by code that shares nothing with
// the project's virtual engine) writes run directories with one effect of DESIGN.md's list, or none; the REAL
// `noisemon diagnose` binary runs on them as a separate process, told nothing; its report.json must name the
// effect (verdict.effect or verdict.also) and close at least 60 % of the held-out gap; the null data set must give
// `none`. The synthesis itself is held to analytic references first (tones through eq. 4.1, Table 4.1's linear
// preset, the levels the effects are specified by).
//
// Scratch files: <gtest TempDir>/noisemon-indep-<pid>/..., removed at exit unless NOISEMON_KEEP_TEMP is set.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <numeric>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cell_synth.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
constexpr double kPi = std::numbers::pi;

// ------------------------------------------------------------------------------------------ helpers

const fs::path& scratch_root() {
  static const pid_t owner = ::getpid();
  static const fs::path dir = [] {
    const fs::path d = fs::path(::testing::TempDir()) / ("noisemon-indep-" + std::to_string(owner));
    fs::create_directories(d);
    return d;
  }();
  static const struct Remover {
    ~Remover() {
      if (::getpid() != owner || std::getenv("NOISEMON_KEEP_TEMP")) return;
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  } remover;
  return dir;
}

fs::path scratch(const std::string& name) {
  const fs::path d = scratch_root() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// The real records, or a skip (a failure under CI=true) when they are missing.
const indep::Sources* sources() {
  static const std::string dir = std::string(NOISEMON_SHARED_DIR) + "/data/real";
  static const bool present = fs::exists(dir + "/yanmar_l100v_fired_18Nm.txt") && fs::exists(dir + "/yanmar_l100v_motored.txt");
  if (!present) return nullptr;
  static const indep::Sources s = indep::load_sources(dir);
  return &s;
}

#define REQUIRE_SOURCES()                                                                        \
  const indep::Sources* src = sources();                                                         \
  if (!src) {                                                                                    \
    if (std::getenv("CI")) FAIL() << "real Yanmar records missing under " NOISEMON_SHARED_DIR;   \
    GTEST_SKIP() << "real Yanmar records not found under " NOISEMON_SHARED_DIR "/data/real";     \
  }

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

double num(const json& j) { return j.is_number() ? j.get<double>() : std::nan(""); }

// Amplitude and phase of the DFT bin k of a record (an exact bin: no leakage).
std::complex<double> bin(const std::vector<double>& y, std::size_t k) {
  std::complex<double> acc(0.0, 0.0);
  const double n = static_cast<double>(y.size());
  for (std::size_t i = 0; i < y.size(); ++i) acc += y[i] * std::polar(1.0, -2 * kPi * static_cast<double>(k * i % y.size()) / n);
  return 2.0 * acc / n;
}

double energy_mean_db(const std::vector<double>& levels_db) {
  double e = 0;
  for (double l : levels_db) e += std::pow(10.0, l / 10.0) / static_cast<double>(levels_db.size());
  return 10.0 * std::log10(e);
}

// ------------------------------------------------------------------------------------------ the synthesis

TEST(IndependentSynth, ReadsTheRealRecordsWithTheirPeggingRow) {
  REQUIRE_SOURCES();
  for (const indep::CycleTable* t : {&src->fired, &src->motored}) {
    ASSERT_EQ(t->cycles_bar.size(), 60u);
    ASSERT_EQ(t->crank_deg.size(), 3600u);
    EXPECT_DOUBLE_EQ(t->crank_deg.front(), -180.0);
    EXPECT_NEAR(t->crank_deg.back(), 539.8, 1e-9);
    for (const auto& c : t->cycles_bar) EXPECT_EQ(c.front(), t->cycles_bar[0].front());  // the pegging value
  }
  // The fired record's mean peak: about 66 bar near 10 deg ATDC (data README: 18 N m, SOI 9.6 deg BTDC).
  double peak = 0;
  std::size_t at = 0;
  for (std::size_t i = 0; i < 3600; ++i) {
    double m = 0;
    for (const auto& c : src->fired.cycles_bar) m += c[i] / 60.0;
    if (m > peak) peak = m, at = i;
  }
  EXPECT_NEAR(peak, 65.6, 1.0);
  EXPECT_NEAR(src->fired.crank_deg[at], 9.6, 3.0);
}

TEST(IndependentSynth, Eq41IsTable41sLinearPresetAsAMassSpringDamper) {
  // Table 4.1 "linear": k1 9.87e8 N/m, b1 2.20e4 N s/m, m 1 kg, y = C0 z + C1 z', C0 7467.57, C1 11.885.
  for (double f = 20; f <= 20000; f *= 1.1) {
    const std::complex<double> s(0.0, 2 * kPi * f);
    const std::complex<double> msd = (7467.57 + 11.885 * s) / (s * s + 2.20e4 * s + 9.87e8);
    EXPECT_NEAR(20 * std::log10(std::abs(indep::eq41(f)) / std::abs(msd)), 0.0, 0.05) << f << " Hz";
  }
  EXPECT_NEAR(std::abs(indep::resonance(1600, 1600, 5) - 1.0), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(indep::resonance(1600 * 1.1, 1600, 5)), 1 / std::sqrt(1 + 25 * std::pow(1.1 - 1 / 1.1, 2)), 1e-12);
  EXPECT_NEAR(indep::a_weighting_db(1000), 0.0, 0.01);  // IEC 61672-1 Table 3
  EXPECT_NEAR(indep::a_weighting_db(100), -19.1, 0.05);
  EXPECT_NEAR(indep::a_weighting_db(10000), -2.5, 0.05);
}

TEST(IndependentSynth, ATonePassesTheSynthesisWithEq41sMagnitudeAndPhaseAndTheDelay) {
  // One period of 0.5 s; the input at the crank-angle rate of 0.2 deg at 1500 and at 1800 rpm (45 and 54 kHz),
  // the output at 51.2 kHz: y(t) = |H| cos(2 pi f (t - tau) + phi + arg H), tau = 1.75 / 343 s.
  const double period = 0.5, tau = 1.75 / 343.0, phi = 0.3;
  const std::size_t n_out = 25600;
  double worst_db = 0, worst_rad = 0, worst_sample = 0;
  for (const std::size_t n_in : {22500u, 27000u})
    for (const double f : {20.0, 100.0, 1000.0, 1600.0, 5000.0, 12500.0, 20000.0}) {
      std::vector<double> u(n_in);
      for (std::size_t i = 0; i < n_in; ++i) u[i] = std::cos(2 * kPi * f * period * static_cast<double>(i) / n_in + phi);
      const auto y = indep::radiate(u, n_out, period, [&](double g) { return indep::eq41(g) * std::polar(1.0, -2 * kPi * g * tau); });
      const std::complex<double> h = indep::eq41(f);
      const std::complex<double> got = bin(y, static_cast<std::size_t>(std::lround(f * period)));
      const double want_phase = phi + std::arg(h) - 2 * kPi * f * tau;
      worst_db = std::max(worst_db, std::abs(20 * std::log10(std::abs(got) / std::abs(h))));
      worst_rad = std::max(worst_rad, std::abs(std::arg(got * std::polar(1.0, -want_phase))));
      for (std::size_t i = 0; i < n_out; i += 97) {
        const double t = period * static_cast<double>(i) / n_out;
        worst_sample = std::max(worst_sample, std::abs(y[i] - std::abs(h) * std::cos(2 * kPi * f * t + want_phase)) / std::abs(h));
      }
    }
  std::printf("tones 20 Hz ... 20 kHz through the synthesis: |H| within %.2e dB, phase within %.2e rad, waveform within %.2e of |H|\n",
              worst_db, worst_rad, worst_sample);
  EXPECT_LT(worst_db, 0.05);
  EXPECT_LT(worst_rad, 1e-3);
  EXPECT_LT(worst_sample, 1e-6);
}

// Mean square above 4 kHz at 1800 rpm (54 kHz crank-angle rate) of x per 90 deg crank window (-360 + 90 w ...).
std::array<double, 8> hf_ms_per_window(const std::vector<double>& x) {
  const std::vector<double> lp = indep::lowpass(x, 4000.0 / 54000.0);
  std::array<double, 8> ms{};
  for (std::size_t i = 0; i < x.size(); ++i) ms[(i % 3600) / 450] += (x[i] - lp[i]) * (x[i] - lp[i]) / (x.size() / 8.0);
  return ms;
}

// Per window: recorded minus clean mean square above 4 kHz (what the chain adds in power), and the clean's share.
void check_floor_is_stationary(const char* what, const indep::CellPressure& p, std::size_t loud_window) {
  const auto rec = hf_ms_per_window(p.recorded_bar), clean = hf_ms_per_window(p.clean_bar);
  double lo = 1e300, hi = 0;
  std::printf("%s, above 4 kHz per 90 deg window from -360 deg: recorded / heard / unheard bar rms\n   ", what);
  std::size_t quietest = 0;
  for (std::size_t w = 0; w < 8; ++w) {
    const double unheard = rec[w] - clean[w];
    lo = std::min(lo, unheard), hi = std::max(hi, unheard);
    if (rec[w] < rec[quietest]) quietest = w;
    std::printf(" %.3f/%.3f/%.3f", std::sqrt(rec[w]), std::sqrt(clean[w]), std::sqrt(std::max(0.0, unheard)));
  }
  std::printf("\n");
  // What the engine does not hear is the chain's stationary floor, 0.1 ... 0.3 bar rms above 4 kHz (data README).
  EXPECT_GT(lo, 0.0) << what;
  EXPECT_LT(10 * std::log10(hi / lo), 2.0) << what << ": the unheard part is not stationary";
  EXPECT_GT(std::sqrt(hi), 0.05) << what;
  EXPECT_LT(std::sqrt(hi), 0.3) << what;
  // In the quietest window the record is mostly floor; where it is loud (the gas ringing) the engine hears most.
  EXPECT_LT(clean[quietest], rec[quietest] / 2) << what;
  EXPECT_GT(clean[loud_window], rec[loud_window] / 2) << what;
}

TEST(IndependentSynth, PressureCsvKeepsTheRecordWhileTheEngineHearsItLessItsStationaryFloor) {
  REQUIRE_SOURCES();
  indep::Condition c{"check", 1800, 1.0, false, false, 5, 16};
  const indep::CellPressure p = indep::condition_pressure(*src, c, 1800);
  ASSERT_EQ(p.recorded_bar.size(), 16u * 3600u);
  // Load scale 1: pressure.csv is the record itself (cycle k = column 5+k's 360 ... 539.8 deg, then 5+k+1's rest).
  EXPECT_EQ(p.recorded_bar[0], src->fired.cycles_bar[5][2700]);
  EXPECT_EQ(p.recorded_bar[900 + 3600 * 3], src->fired.cycles_bar[5 + 4][0]);
  check_floor_is_stationary("fired 1800 rpm", p, 4);  // 0 ... 90 deg: combustion
  // A scaled load keeps the record's own noise (recorded - clean at scale 1), sample for sample, unscaled.
  c.load_scale = 1.3;
  const indep::CellPressure q = indep::condition_pressure(*src, c, 1800);
  double worst = 0;
  for (std::size_t i = 0; i < q.recorded_bar.size(); ++i)
    worst = std::max(worst, std::abs(q.recorded_bar[i] - q.clean_bar[i] - (p.recorded_bar[i] - p.clean_bar[i])));
  EXPECT_LT(worst, 1e-9);
  const indep::CellPressure m = indep::condition_pressure(*src, {"motored", 1800, 1.0, true, false, 5, 16}, 1800);
  EXPECT_EQ(m.recorded_bar[900 + 3600 * 3], src->motored.cycles_bar[5 + 4][0]);
  check_floor_is_stationary("motored 1800 rpm", m, 2);  // -180 ... -90 deg: the burst at intake valve closing
}

TEST(IndependentSynth, EffectsHaveTheLevelsTheyAreSpecifiedBy) {
  REQUIRE_SOURCES();
  const indep::Chain chain;
  const auto conditions = indep::default_conditions(16);
  const indep::Condition& c = conditions[1];  // fired 1800 rpm
  const indep::Run null = indep::synthesize(*src, c, 1, chain, {});
  auto diff_levels = [&](const indep::Effects& fx, std::vector<double>* ratio = nullptr) {
    const indep::Run r = indep::synthesize(*src, c, 1, chain, fx);
    std::vector<double> l;
    for (int m = 0; m < indep::kMics; ++m) {
      std::vector<double> d(r.mics_pa[m].size());
      for (std::size_t i = 0; i < d.size(); ++i) d[i] = r.mics_pa[m][i] - null.mics_pa[m][i];
      l.push_back(indep::level_db(d, chain.fs_hz, true));
      if (ratio) ratio->push_back(indep::level_db(r.mics_pa[m], chain.fs_hz, true) - indep::level_db(null.mics_pa[m], chain.fs_hz, true));
    }
    return l;
  };
  std::vector<double> engine;
  for (const auto& y : null.mics_pa) engine.push_back(indep::level_db(y, chain.fs_hz, true));
  std::printf("null run %s at %.1f rpm: array Lp(A) %.1f dB\n", c.name.c_str(), null.time.speed_rpm, energy_mean_db(engine));
  indep::Effects bg;
  bg.background_dba = 85;
  for (double l : diff_levels(bg)) EXPECT_NEAR(l, 85.0, 1e-6);
  indep::Effects mech;
  mech.mechanical_dba = 90;
  EXPECT_NEAR(energy_mean_db(diff_levels(mech)), 90 + 10 * std::log10(null.time.speed_rpm / 1800), 1e-6);
  indep::Effects gain;
  gain.mic_gain_db = 3;
  std::vector<double> ratio;
  diff_levels(gain, &ratio);
  for (int m = 0; m < indep::kMics; ++m) EXPECT_NEAR(ratio[m], m == 3 ? 3.0 : 0.0, 1e-9) << "mic " << m + 1;
}

// ------------------------------------------------------------------------------------------ the diagnosis

// Cycles per condition in the diagnosis family. Fewer do not make it faster (diagnose re-simulates --fit-cycles, 8,
// per condition in its fits, whatever the data holds; 12 instead of 16 saved nothing) and changed verdicts.
constexpr int kCyclesPerCondition = 16;

struct Case {
  const char* label;
  const char* expect;  // DESIGN.md's effect name, or "none"
  indep::Effects fx;
};

void PrintTo(const Case& c, std::ostream* os) { *os << c.label << " (expect " << c.expect << ")"; }

indep::Effects with(void (*set)(indep::Effects&)) {
  indep::Effects fx;
  set(fx);
  return fx;
}

void print_report(const char* label, const json& r, double seconds) {
  const json& v = r["verdict"];
  std::string also;
  for (const auto& a : v.value("also", json::array())) also += " + " + a.get<std::string>();
  std::printf("[%s] verdict %s%s, held-out gap %.2f -> %.2f dB (%.0f %% closed), %.0f s\n", label,
              v["effect"].get<std::string>().c_str(), also.c_str(), num(v["heldout_rms_before_db"]),
              num(v["heldout_rms_after_db"]), 100 * num(v["gap_closed_fraction"]), seconds);
  for (std::size_t i = 0; i < std::min<std::size_t>(4, r["candidates"].size()); ++i) {
    const json& c = r["candidates"][i];
    std::printf("    %-18s gap %6.2f dB  closed %5.0f %%  %s\n", c["effect"].get<std::string>().c_str(), num(c["heldout_rms_db"]),
                100 * num(c["gap_closed_fraction"]), c.value("significant", false) ? "significant" : "");
  }
  const json& w = r["where"];
  if (!w.contains("gap_per_band_rms_db") || !w.contains("bands_hz")) return;
  std::vector<std::size_t> order(w["bands_hz"].size());
  std::iota(order.begin(), order.end(), 0);
  auto gap = [&](std::size_t b) { const double g = num(w["gap_per_band_rms_db"][b]); return std::isfinite(g) ? std::abs(g) : -1.0; };
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return gap(a) > gap(b); });
  std::printf("    worst bands (baseline gap rms over held-out conditions):");
  for (std::size_t i = 0; i < std::min<std::size_t>(5, order.size()); ++i)
    std::printf(" %g Hz %.2f dB;", num(w["bands_hz"][order[i]]), num(w["gap_per_band_rms_db"][order[i]]));
  std::printf("\n");
  if (w.contains("floors") && w["floors"].contains("summary") && w["floors"]["summary"].is_string())
    std::printf("    floors: %s\n", w["floors"]["summary"].get<std::string>().c_str());
}

// diagnose.log's "pressure floor <condition> ...; estimated ..." lines.
void print_floor_lines(const std::string& log_text) {
  std::size_t at = 0;
  while (at < log_text.size()) {
    const std::size_t end = std::min(log_text.find('\n', at), log_text.size());
    const std::string line = log_text.substr(at, end - at);
    if (line.rfind("pressure floor ", 0) == 0) std::printf("    %s\n", line.c_str());
    at = end + 1;
  }
}

// The real `noisemon diagnose` on the independent cell's run directories with one withheld effect (or none): the
// verdict names it (or its partner does) and closes at least 60 % of the held-out gap; the null reads `none`.
void expect_verdict(const Case& k) {
  REQUIRE_SOURCES();
  const fs::path dir = scratch(k.label);
  indep::write_campaign(*src, indep::default_conditions(kCyclesPerCondition), indep::Chain{}, k.fx, dir / "runs");
  const std::string cmd = quote(NOISEMON_PATH) + " diagnose " + quote((dir / "runs").string()) + " -o " +
                          quote((dir / "diag").string()) + " --bootstrap 100 --no-progress --force > " +
                          quote((dir / "diagnose.log").string()) + " 2>&1";
  const auto t0 = std::chrono::steady_clock::now();
  const int status = std::system(cmd.c_str());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::ifstream log(dir / "diagnose.log");
  const std::string log_text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  ASSERT_EQ(status, 0) << cmd << "\n" << log_text;
  std::ifstream in(dir / "diag" / "report.json");
  ASSERT_TRUE(in) << "no report.json\n" << log_text;
  const json r = json::parse(in);
  print_report(k.label, r, seconds);
  print_floor_lines(log_text);
  const json& v = r["verdict"];
  const std::string effect = v["effect"].get<std::string>();
  if (std::string(k.expect) == "none") {
    EXPECT_EQ(effect, "none");
    return;
  }
  const json also = v.value("also", json::array());
  const bool named = effect == k.expect || std::find(also.begin(), also.end(), json(k.expect)) != also.end();
  EXPECT_TRUE(named) << "verdict " << effect << " " << also.dump() << ", expected " << k.expect;
  EXPECT_LT(num(v["heldout_rms_after_db"]), num(v["heldout_rms_before_db"]));
  EXPECT_GE(num(v["gap_closed_fraction"]), 0.6);
}

class IndependentDiagnosis : public ::testing::TestWithParam<Case> {};

TEST_P(IndependentDiagnosis, VerdictNamesTheWithheldEffectAndClosesAtLeast60PercentOfTheGap) { expect_verdict(GetParam()); }

// Magnitudes: the engine here is 108.6 dB(A) at 1800 rpm (array average). A flat +-1 dB directivity spreads the
// microphones at every frequency, so a miscalibration must stand out of it: 4 dB (a wrong sensitivity entered in
// the DAQ, 40 instead of 25 mV/Pa). Background 100 dB(A): a loud dynamometer and ventilation, 9 dB below the engine.
INSTANTIATE_TEST_SUITE_P(
    WithheldEffects, IndependentDiagnosis,
    ::testing::Values(Case{"null", "none", {}},
                      Case{"second_mode_8db_1600hz", "second_mode", with([](indep::Effects& f) { f.second_mode_db = 8; })},
                      Case{"mic_gain_4db_mic4", "mic_gain", with([](indep::Effects& f) { f.mic_gain_db = 4; })},
                      Case{"background_noise_100dba", "background_noise", with([](indep::Effects& f) { f.background_dba = 100; })},
                      Case{"speed_dependence_4db_per_krpm", "speed_dependence",
                           with([](indep::Effects& f) { f.speed_db_per_krpm = 4; })}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.label); });

class IndependentDiagnosisOpen : public ::testing::TestWithParam<Case> {};

// DISABLED (issue 9, open; run with --gtest_also_run_disabled_tests): the independent cell's crank-locked impacts
// (two decaying tones, 2.5 and 5.2 kHz, 0.4 ms, at four fixed angles; fixed energy per impact) are not yet read
// right. At 95 dB(A) the verdict ties background_noise and mechanical_noise (50 % closed each); at 100 dB(A)
// mechanical_noise closes 66 % and background_noise 63 %, and the simpler background is named. Both leave about
// 1 dB of the whole-cycle band gap at 0.8-2.5 kHz (and the locked one makes 250-500 Hz worse); it fits a speed
// exponent of 0.6-0.75 (true: 1). Not the impacts' phase lock to the combustion noise: with 2 deg of timing jitter
// per impact the tie stays (62 / 59 %). Nor the motored runs' bands at the pressure floor being left out of the
// additive fits: fitting the impacts on them too changed 66 / 63 % to 67 / 64 %.
TEST_P(IndependentDiagnosisOpen, DISABLED_VerdictNamesTheWithheldEffectAndClosesAtLeast60PercentOfTheGap) {
  expect_verdict(GetParam());
}

INSTANTIATE_TEST_SUITE_P(
    WithheldEffects, IndependentDiagnosisOpen,
    ::testing::Values(Case{"mechanical_noise_95dba", "mechanical_noise", with([](indep::Effects& f) { f.mechanical_dba = 95; })},
                      Case{"mechanical_noise_100dba", "mechanical_noise", with([](indep::Effects& f) { f.mechanical_dba = 100; })},
                      Case{"mechanical_noise_95dba_jitter2", "mechanical_noise", with([](indep::Effects& f) { f.mechanical_dba = 95; f.mechanical_jitter_deg = 2; })}),
    [](const ::testing::TestParamInfo<Case>& i) { return std::string(i.param.label); });

}  // namespace
