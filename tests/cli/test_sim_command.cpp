// `noisemon sim` end to end: the real binary writes run directories that drivers/formats/run_dir reads back, with the
// injected effect visible against an independent expectation (its documented definition, computed here), and
// bad options fail with errors that name what is wrong. With the real Yanmar cycles (shared data): the
// imported fired and motored pressures drive the virtual engine; mechanical_noise is the same in both and follows
// its documented level and speed law, and the combustion-driven sound is what eq. 4.1 (evaluated here by FFT on
// the real pressure) predicts for each, so fired is louder than motored by what combustion adds. The realistic test
// cell: the configured pressure floor measured in pressure.csv against an ideal chain's run and recorded in each
// run.json (without the transducer_noise effect, which adds in quadrature on top), and the engine-off background
// run, which the diagnosis loader takes as the floor.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/band_data.hpp"
#include "drivers/formats/run_dir.hpp"
#include "dsp/math_constants.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/required.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace fs = std::filesystem;
using noisemon::drivers::formats::read_run_dir;
using noisemon::drivers::formats::RunDir;
using cd = std::complex<double>;

namespace {

using noisemon::kPi;
constexpr double kPref = 20e-6;
using noisemon::test::kNoisemon;

fs::path sim_temp(const std::string& name) {
  const fs::path p = noisemon::test::unique_temp("sim_command_" + name);  // per test and process
  fs::remove_all(p);
  return p;
}

struct Result {
  int status = -1;
  std::string out, err;
};

// Runs noisemon with the arguments; stdout and stderr captured; killed after the timeout (status -1).
Result run_noisemon(const std::vector<std::string>& args, std::chrono::seconds timeout = std::chrono::seconds(120)) {
  static int counter = 0;
  const fs::path out = sim_temp("stdout" + std::to_string(counter)),
                 err = sim_temp("stderr" + std::to_string(counter++));
  const pid_t pid = fork();
  if (pid == 0) {
    if (!std::freopen(out.c_str(), "w", stdout) || !std::freopen(err.c_str(), "w", stderr)) _exit(126);
    std::vector<char*> argv{const_cast<char*>(kNoisemon.c_str())};
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  Result r;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) {
      r.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (r.status == -1) {
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
  }
  r.out = noisemon::test::slurp(out);
  r.err = noisemon::test::slurp(err);
  return r;
}

std::vector<double> channel(const RunDir& run, std::size_t ch) {
  std::vector<double> x(run.mic_pa.size() / run.mic_count);
  for (std::size_t f = 0; f < x.size(); ++f) x[f] = run.mic_pa[f * run.mic_count + ch];
  return x;
}

double mean_square(const std::vector<double>& x) {
  double s = 0.0;
  for (double v : x) s += v * v;
  return s / static_cast<double>(x.size());
}

// In-place radix-2 FFT (forward, unscaled).
void fft(std::vector<cd>& a) {
  const std::size_t n = a.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(a[i], a[j]);
  }
  for (std::size_t len = 2; len <= n; len <<= 1) {
    const cd wl = std::polar(1.0, -2.0 * kPi / static_cast<double>(len));
    for (std::size_t i = 0; i < n; i += len) {
      cd w(1.0);
      for (std::size_t k = 0; k < len / 2; ++k, w *= wl) {
        const cd u = a[i + k], v = a[i + k + len / 2] * w;
        a[i + k] = u + v;
        a[i + k + len / 2] = u - v;
      }
    }
  }
}

// IEC 61672-1 A-weighting as a power ratio (written out here, independent of dsp/weighting).
double a_weight_power(double f) {
  const double f2 = f * f, c1 = 20.598997 * 20.598997, c2 = 107.65265 * 107.65265, c3 = 737.86223 * 737.86223,
               c4 = 12194.217 * 12194.217;
  const double ra = c4 * f2 * f2 / ((f2 + c1) * std::sqrt((f2 + c2) * (f2 + c3)) * (f2 + c4));
  return ra * ra * std::pow(10.0, 2.0 / 10.0);
}

// A-weighted mean squares of x (sampled at fs) through a transfer h, by FFT (Parseval): element 0 over
// 20 Hz - 20 kHz, then one per octave band of `octaves` (centre frequencies).
template <class H>
std::vector<double> weighted_mean_squares(const std::vector<double>& x, double fs, H h,
                                          const std::vector<double>& octaves) {
  std::size_t n = 1;
  while (n < x.size()) n <<= 1;
  std::vector<cd> a(n, 0.0);
  double mean = 0.0;
  for (double v : x) mean += v / static_cast<double>(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) a[i] = x[i] - mean;
  fft(a);
  std::vector<double> e(1 + octaves.size(), 0.0);
  for (std::size_t k = 1; k < n / 2; ++k) {
    const double f = fs * static_cast<double>(k) / static_cast<double>(n);
    if (f < 20.0 || f > 20000.0) continue;
    const double v =
        2.0 * std::norm(a[k] * h(f)) * a_weight_power(f) / static_cast<double>(n) / static_cast<double>(x.size());
    e[0] += v;
    for (std::size_t b = 0; b < octaves.size(); ++b)
      if (f >= octaves[b] / std::sqrt(2.0) && f < octaves[b] * std::sqrt(2.0)) e[b + 1] += v;
  }
  return e;
}
double db(double ms) { return 10.0 * std::log10(ms / (kPref * kPref)); }

const std::vector<std::string> kDesignEffects{"cubic_damping",    "cubic_stiffness",  "second_mode",
                                              "mechanical_noise", "background_noise", "transducer_noise",
                                              "mic_gain",         "speed_dependence"};

}  // namespace

TEST(SimCommand, HelpAndListEffectsNameEveryDesignEffectWithItsUnit) {
  const Result help = run_noisemon({"sim", "--help"});
  ASSERT_EQ(help.status, 0) << help.err;
  const Result list = run_noisemon({"sim", "--list-effects"});
  ASSERT_EQ(list.status, 0) << list.err;
  for (const auto& name : kDesignEffects) {
    EXPECT_NE(help.out.find("  " + name + "  ["), std::string::npos) << name << " missing from sim --help";
    EXPECT_NE(list.out.find("  " + name + "  ["), std::string::npos) << name << " missing from --list-effects";
  }
  for (const char* unit : {"[N s^3/m^3]", "[N/m^3]", "[dB(A)]", "[bar rms]", "[dB per 1000 rpm]"})
    EXPECT_NE(list.out.find(unit), std::string::npos) << unit;
  for (const char* option : {"--pressure-floor", "--background-run", "--ideal-cell"})
    EXPECT_NE(help.out.find(option), std::string::npos) << option << " missing from sim --help";
}

// mic_gain: with the same seed, the chosen microphone is exactly 10^(M/20) times its value without the effect and
// every other channel and the pressure are unchanged; transducer_noise: pressure.csv minus the same run without it
// is white noise of the documented rms per encoder sample, the microphones are unchanged; the realistic run minus
// an ideal chain's (--pressure-floor 0) is the configured floor, which run.json records.
TEST(SimCommand, WritesRunDirectoriesThatLoadAndCarryTheInjectedEffect) {
  const fs::path base = sim_temp("small");
  const std::vector<std::string> common{"sim", "--condition", "idle_mi18", "--cycles",
                                        "3",   "--seed",      "5",         "--no-progress"};
  auto args = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = common;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const Result null = run_noisemon(args({"-o", (base / "null").string()}));
  ASSERT_EQ(null.status, 0) << null.err;
  const Result gain = run_noisemon(args({"--effect", "mic_gain=6,mic=3", "-o", (base / "gain").string()}));
  ASSERT_EQ(gain.status, 0) << gain.err;
  const Result noise = run_noisemon(args({"--effect", "transducer_noise=0.1", "-o", (base / "noise").string()}));
  ASSERT_EQ(noise.status, 0) << noise.err;
  const Result ideal = run_noisemon(args({"--pressure-floor", "0", "-o", (base / "ideal").string()}));
  ASSERT_EQ(ideal.status, 0) << ideal.err;

  const RunDir a = read_run_dir(base / "null" / "idle_mi18");
  const RunDir b = read_run_dir(base / "gain" / "idle_mi18");
  const RunDir c = read_run_dir(base / "noise" / "idle_mi18");
  EXPECT_EQ(a.condition.name, "idle_mi18");
  EXPECT_DOUBLE_EQ(a.condition.speed_rpm, 3050.0);
  EXPECT_DOUBLE_EQ(a.condition.soi_deg_btdc, 18.0);
  EXPECT_FALSE(a.condition.motored);
  ASSERT_EQ(a.mic_count, 10u);
  EXPECT_EQ(a.mic_positions_m.size(), 10u);
  // Three whole cycles of 0.2-degree encoder samples from -360 deg, and microphones over the same time.
  ASSERT_EQ(a.crank_deg.size(), 3u * 3600u);
  EXPECT_DOUBLE_EQ(a.crank_deg.front(), -360.0);
  EXPECT_NEAR(a.time_s.back(), 3 * 120.0 / 3050.0, 2e-3);
  EXPECT_NEAR(static_cast<double>(a.mic_pa.size() / 10) / a.mic_rate_hz, a.time_s.back(), 2.0 / a.mic_rate_hz);
  // The engine is running: peak cylinder pressure of a fired diesel and an audible engine.
  double pmax = 0.0;
  for (double p : a.pressure_pa) pmax = std::max(pmax, p);
  EXPECT_GT(pmax, 30e5);
  EXPECT_GT(db(mean_square(channel(a, 0))), 60.0);

  ASSERT_EQ(b.mic_pa.size(), a.mic_pa.size());
  const double expected = std::pow(10.0, 6.0 / 20.0);
  for (std::size_t m = 0; m < 10; ++m) {
    const auto xa = channel(a, m), xb = channel(b, m);
    double worst = 0.0;
    for (std::size_t i = 0; i < xa.size(); ++i)
      worst = std::max(worst, std::abs(xb[i] - (m == 2 ? expected : 1.0) * xa[i]) / (1e-3 + std::abs(xa[i])));
    EXPECT_LT(worst, 1e-6) << "microphone " << m + 1;  // float32 WAV rounding
  }
  EXPECT_EQ(b.pressure_pa, a.pressure_pa);

  // Transducer noise: 0.1 bar rms per encoder sample, whatever the edge rate (quantised by the same ADC as the rest).
  ASSERT_EQ(c.pressure_pa.size(), a.pressure_pa.size());
  EXPECT_EQ(c.mic_pa, a.mic_pa);
  std::vector<double> d(a.pressure_pa.size());
  double lag1 = 0.0;
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = c.pressure_pa[i] - a.pressure_pa[i];
  for (std::size_t i = 1; i < d.size(); ++i) lag1 += d[i] * d[i - 1];
  const double rms = std::sqrt(mean_square(d)), want = 0.1e5;
  std::printf("transducer_noise=0.1: rms %.1f Pa (documented %.1f Pa), lag-1 correlation %.3f\n", rms, want,
              lag1 / static_cast<double>(d.size() - 1) / (rms * rms));
  EXPECT_NEAR(rms / want, 1.0, 0.05);  // pressure.csv is written in bar with enough digits for this
  EXPECT_LT(std::abs(lag1 / static_cast<double>(d.size() - 1)) / (rms * rms), 0.05);  // white

  // The configured floor: 0.02 bar white and the 16-bit step over 250 bar in quadrature, measured against the ideal
  // chain's run (the same true pressure, gas ringing and all) and recorded in run.json; the effect is not recorded.
  const RunDir e = read_run_dir(base / "ideal" / "idle_mi18");
  ASSERT_EQ(e.pressure_pa.size(), a.pressure_pa.size());
  EXPECT_EQ(e.mic_pa, a.mic_pa);  // the microphones hear the true pressure
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = a.pressure_pa[i] - e.pressure_pa[i];
  const double step_bar = 250.0 / 65536.0, floor_bar = std::sqrt(0.02 * 0.02 + step_bar * step_bar / 12.0);
  std::printf("pressure floor: measured %.5f bar rms per encoder sample, configured %.5f bar\n",
              1e-5 * std::sqrt(mean_square(d)), floor_bar);
  EXPECT_NEAR(1e-5 * std::sqrt(mean_square(d)) / floor_bar, 1.0, 0.03);
  ASSERT_TRUE(a.pressure_noise_floor_bar.has_value());
  EXPECT_NEAR(*a.pressure_noise_floor_bar, floor_bar, 1e-12);
  ASSERT_TRUE(c.pressure_noise_floor_bar.has_value());
  EXPECT_NEAR(*c.pressure_noise_floor_bar, floor_bar, 1e-12);  // transducer_noise is the unknown: not recorded
  ASSERT_TRUE(e.pressure_noise_floor_bar.has_value());
  EXPECT_EQ(*e.pressure_noise_floor_bar, 0.0);

  // truth.json says what was injected.
  const auto truth = nlohmann::json::parse(noisemon::test::slurp(base / "gain" / "truth.json"));
  ASSERT_EQ(truth.at("effects").size(), 1u);
  EXPECT_EQ(truth["effects"][0]["name"], "mic_gain");
  EXPECT_EQ(truth["effects"][0]["magnitude"], 6.0);
  EXPECT_EQ(truth["effects"][0]["qualifiers"]["mic"], 3.0);
  EXPECT_EQ(truth["runs"][0]["dir"], "idle_mi18");
}

TEST(SimCommand, BadOptionsFailWithClearErrorsAndWriteNothing) {
  const fs::path out = sim_temp("bad");
  const std::vector<std::string> run{"sim", "--condition",   "idle_mi12", "--cycles",
                                     "1",   "--no-progress", "-o",        out.string()};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = run;
    a.insert(a.end(), extra.begin(), extra.end());
    return run_noisemon(a);
  };
  struct Case {
    std::vector<std::string> extra;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases{
      {{"--effect", "engine_wobble=3"}, {"unknown effect \"engine_wobble\"", "valid effects", "cubic_damping"}},
      {{"--effect", "mic_gain=loud"}, {"mic_gain=loud", "\"loud\" is not a finite number"}},
      {{"--effect", "mic_gain=99"}, {"mic_gain=99", "outside the accepted range"}},
      {{"--effect", "second_mode=6,width=3"}, {"unknown qualifier \"width\"", "hz, q"}},
      {{"--effect", "mic_gain=3,mic=12"}, {"microphone 12 does not exist"}},
      {{"--effect", "mic_gain", "--effect", "mic_gain=2"}, {"mic_gain given twice"}},
      {{"--condition", "idle_mi13"}, {"unknown condition \"idle_mi13\"", "valid conditions", "full_mi24"}},
  };
  for (const auto& c : cases) {
    const Result r = with(c.extra);
    EXPECT_NE(r.status, 0) << c.extra.back();
    for (const auto& s : c.says)
      EXPECT_NE(r.err.find(s), std::string::npos) << "stderr for " << c.extra.back() << ": " << r.err;
    EXPECT_FALSE(fs::exists(out / "idle_mi12")) << "nothing is written on a bad option";
  }
  {
    const Result r = run_noisemon({"sim", "--effect", "mic_gain", "-o", out.string()});
    EXPECT_NE(r.status, 0);
    EXPECT_NE(r.err.find("--condition"), std::string::npos) << r.err;
  }
  // An existing run is never replaced without --force.
  ASSERT_EQ(with({}).status, 0);
  const auto stamp = fs::last_write_time(out / "idle_mi12" / "mics.wav");
  const std::string before = noisemon::test::slurp(out / "idle_mi12" / "pressure.csv");
  const Result again = with({"--seed", "2"});
  EXPECT_NE(again.status, 0);
  EXPECT_NE(again.err.find("already holds a run; use --force"), std::string::npos) << again.err;
  EXPECT_NE(again.err.find((out / "idle_mi12").string()), std::string::npos) << again.err;
  EXPECT_EQ(noisemon::test::slurp(out / "idle_mi12" / "pressure.csv"), before);
  EXPECT_EQ(fs::last_write_time(out / "idle_mi12" / "mics.wav"), stamp);
  const Result forced = with({"--seed", "2", "--force"});
  EXPECT_EQ(forced.status, 0) << forced.err;
  EXPECT_NE(noisemon::test::slurp(out / "idle_mi12" / "pressure.csv"), before);
}

// ------------------------------------------------------------------------------------------ real Yanmar cycles

namespace {

std::string shared_table(const std::string& name) { return noisemon::test::reference_file(name); }

// The table imported (noisemon import) and exported (noisemon export) as a pressure-only run directory.
fs::path import_table(const std::string& table, const std::string& name, bool motored, const fs::path& base) {
  const fs::path log = base / (name + ".lcmlog"), dir = base / "pressure" / name;
  std::vector<std::string> args{"import", "--cycles-table", table, "--rpm",     "1799.9", "--condition",
                                name,     "--no-progress",  "-o",  log.string()};
  if (motored)
    args.push_back("--motored");
  else
    args.insert(args.end(), {"--load", "18", "--soi", "9.6"});
  const Result imp = run_noisemon(args);
  EXPECT_EQ(imp.status, 0) << imp.err;
  const Result exp = run_noisemon({"export", log.string(), "--no-progress", "-o", dir.string()});
  EXPECT_EQ(exp.status, 0) << exp.err;
  return dir;
}

// The pressure of a run on a uniform time grid at its most common sample step (the import resamples to 40 kHz;
// a missing sample is filled linearly); returns the sample rate.
double uniform_pressure(const RunDir& run, std::vector<double>& p) {
  std::vector<double> steps;
  for (std::size_t i = 1; i < run.time_s.size(); ++i) steps.push_back(run.time_s[i] - run.time_s[i - 1]);
  std::nth_element(steps.begin(), steps.begin() + static_cast<std::ptrdiff_t>(steps.size() / 2), steps.end());
  const double dt = steps[steps.size() / 2];
  p.clear();
  for (std::size_t i = 0; i < run.time_s.size(); ++i) {
    if (i > 0) {
      const double gap = run.time_s[i] - run.time_s[i - 1];
      for (long k = 1; k < std::lround(gap / dt); ++k)
        p.push_back(run.pressure_pa[i - 1] +
                    (run.pressure_pa[i] - run.pressure_pa[i - 1]) * static_cast<double>(k) * dt / gap);
    }
    p.push_back(run.pressure_pa[i]);
  }
  return 1.0 / dt;
}

// Levels (dB, A-weighted; [0] overall, then per octave) of the energy mean over the microphones of a - b (b may be
// null), frames [from, end).
std::vector<double> mic_levels(const RunDir& a, const RunDir* b, std::size_t from, const std::vector<double>& octaves) {
  std::vector<double> e(1 + octaves.size(), 0.0);
  for (std::size_t m = 0; m < a.mic_count; ++m) {
    std::vector<double> x = channel(a, m);
    if (b) {
      const auto y = channel(*b, m);
      for (std::size_t i = 0; i < x.size(); ++i) x[i] -= y[i];
    }
    x.erase(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(from));
    const auto em = weighted_mean_squares(
        x, a.mic_rate_hz, [](double) { return 1.0; }, octaves);
    for (std::size_t i = 0; i < e.size(); ++i) e[i] += em[i] / a.mic_count;
  }
  for (double& v : e) v = db(v);
  return e;
}

}  // namespace

TEST(SimCommand, RealYanmarFiredAndMotoredCyclesDriveTheVirtualEngine) {
  const std::string fired_table = shared_table("yanmar_l100v_fired_18Nm.txt");
  const std::string motored_table = shared_table("yanmar_l100v_motored.txt");
  if (fired_table.empty() || motored_table.empty())
    GTEST_SKIP() << "Yanmar tables not found under " << NOISEMON_SHARED_DIR << "/data/real";
  const fs::path base = sim_temp("yanmar");
  fs::create_directories(base);
  const fs::path fired_p = import_table(fired_table, "yanmar_fired", false, base);
  const fs::path motored_p = import_table(motored_table, "yanmar_motored", true, base);
  ASSERT_FALSE(HasFailure());
  // Same seed and run names: the "mech" runs differ from the "clean" ones by the impacts alone.
  for (const char* set : {"clean", "mech"}) {
    std::vector<std::string> args{"sim",    "--pressure", fired_p.string(), "--pressure", motored_p.string(),
                                  "--seed", "3",          "--no-progress",  "-o",         (base / set).string()};
    if (std::string(set) == "mech") args.insert(args.end(), {"--effect", "mechanical_noise=80"});
    const Result r = run_noisemon(args);
    ASSERT_EQ(r.status, 0) << r.err;
  }
  const RunDir fired = read_run_dir(base / "clean" / "yanmar_fired");
  const RunDir motored = read_run_dir(base / "clean" / "yanmar_motored");
  const RunDir fired_mech = read_run_dir(base / "mech" / "yanmar_fired");
  const RunDir motored_mech = read_run_dir(base / "mech" / "yanmar_motored");
  const RunDir fired_in = read_run_dir(fired_p);
  // The condition and the real pressure are kept; the microphones are the sim's.
  EXPECT_EQ(fired.condition.name, "yanmar_fired");
  EXPECT_FALSE(fired.condition.motored);
  EXPECT_TRUE(motored.condition.motored);
  EXPECT_DOUBLE_EQ(fired.condition.speed_rpm, 1799.9);
  ASSERT_EQ(fired.pressure_pa.size(), fired_in.pressure_pa.size());
  double worst_p = 0.0;
  for (std::size_t i = 0; i < fired.pressure_pa.size(); ++i)
    worst_p = std::max(worst_p, std::abs(fired.pressure_pa[i] - fired_in.pressure_pa[i]));
  EXPECT_LT(worst_p, 1.0) << "the real pressure is passed through (to the CSV's digits)";
  ASSERT_EQ(fired.mic_count, 10u);
  EXPECT_NEAR(static_cast<double>(fired.mic_pa.size() / 10) / fired.mic_rate_hz, fired.time_s.back(),
              2.0 / fired.mic_rate_hz);

  // Mechanical noise: the documented Leq(A), 80 + 30 log10(1799.9 / 3050), in both, equal within the scatter.
  const std::size_t skip = static_cast<std::size_t>(0.05 * fired.mic_rate_hz);  // the first impacts' delay
  const double documented = 80.0 + 30.0 * std::log10(1799.9 / 3050.0);
  const double mech_fired = mic_levels(fired_mech, &fired, skip, {})[0];
  const double mech_motored = mic_levels(motored_mech, &motored, skip, {})[0];
  // Combustion-driven sound: eq. 4.1 (the linear preset the sim uses) on the real pressure, by FFT, A-weighted;
  // the microphones' energy mean (per-microphone spread has energy mean 1) should match it, overall and per octave.
  const auto eq41 = [](double f) {
    const cd s(0.0, 2.0 * kPi * f);
    const double wb = 2.0 * kPi * 100.0, wn = 2.0 * kPi * 5000.0;
    return 11.885 * (s + wb) / (s * s + 2.0 * 0.35 * wn * s + wn * wn);
  };
  const std::vector<double> octaves{125, 250, 500, 1000, 2000, 4000, 8000, 16000};
  std::vector<double> predicted[2], measured[2];
  const RunDir* runs[2] = {&fired, &motored};
  const fs::path dirs[2] = {fired_p, motored_p};
  for (int k = 0; k < 2; ++k) {
    std::vector<double> p;
    const RunDir in = k == 0 ? fired_in : read_run_dir(dirs[k]);
    const double fs_p = uniform_pressure(in, p);
    predicted[k] = weighted_mean_squares(p, fs_p, eq41, octaves);
    for (double& v : predicted[k]) v = db(v);
    measured[k] = mic_levels(*runs[k], nullptr, skip, octaves);
  }
  std::printf("Yanmar octave bands (A-weighted dB): fc, fired measured / eq. 4.1, motored measured / eq. 4.1\n");
  for (std::size_t b = 0; b < octaves.size(); ++b) {
    std::printf("  %6.0f Hz  %6.1f / %6.1f   %6.1f / %6.1f\n", octaves[b], measured[0][b + 1], predicted[0][b + 1],
                measured[1][b + 1], predicted[1][b + 1]);
    EXPECT_NEAR(measured[0][b + 1], predicted[0][b + 1], 1.5) << octaves[b] << " Hz, fired";
    EXPECT_NEAR(measured[1][b + 1], predicted[1][b + 1], 1.5) << octaves[b] << " Hz, motored";
  }
  std::printf("Yanmar: mechanical_noise=80 at 1799.9 rpm: Leq(A) fired %.2f dB, motored %.2f dB, documented %.2f dB\n",
              mech_fired, mech_motored, documented);
  std::printf("Yanmar: engine sound Lp(A) fired %.2f dB (eq. 4.1 on the pressure: %.2f), motored %.2f dB (%.2f)\n",
              measured[0][0], predicted[0][0], measured[1][0], predicted[1][0]);
  EXPECT_NEAR(mech_fired, documented, 0.5);
  EXPECT_NEAR(mech_motored, documented, 0.5);
  EXPECT_NEAR(mech_fired, mech_motored, 0.3);
  EXPECT_NEAR(measured[0][0], predicted[0][0], 0.5);
  EXPECT_NEAR(measured[1][0], predicted[1][0], 0.5);
  // Combustion noise only in fired: in the octaves where a DI diesel's combustion (the pressure-rise rate) radiates,
  // 500 Hz and 1 kHz, the fired engine is far louder than the motored one, by what the two real pressures predict.
  // (Above 2 kHz both raw tables are dominated by their transducer noise, +-0.5 bar per the data README, so the
  // overall A-weighted difference is only a few dB.)
  for (std::size_t b : {2u, 3u}) {
    EXPECT_GT(measured[0][b + 1] - measured[1][b + 1], 8.0) << octaves[b] << " Hz";
    EXPECT_NEAR(measured[0][b + 1] - measured[1][b + 1], predicted[0][b + 1] - predicted[1][b + 1], 1.5)
        << octaves[b] << " Hz";
  }
}

// --background-run: an engine-off run named "background", which the diagnosis loader takes as the floor: its
// microphones hear only the test cell, its pressure is ambient through the chain; truth.json records the cell.
TEST(SimCommand, BackgroundRunIsTheTestCellAloneAndLoadsAsTheDiagnosisFloor) {
  const fs::path base = sim_temp("background");
  const Result r = run_noisemon({"sim", "--condition", "motored_idle", "--background-run", "--effect",
                                 "background_noise=60", "--effect", "transducer_noise=0.1", "--cycles", "4", "--seed",
                                 "2", "--no-progress", "-o", (base / "runs").string()});
  ASSERT_EQ(r.status, 0) << r.err;
  const RunDir bg = read_run_dir(base / "runs" / "background");
  const RunDir mot = read_run_dir(base / "runs" / "motored_idle");
  EXPECT_EQ(bg.condition.name, "background");
  EXPECT_TRUE(bg.condition.motored);
  ASSERT_EQ(bg.mic_count, 10u);
  // Pressure: the ambient 1 bar read through the chain, its floor plus the injected 0.1 bar.
  double mean = 0.0;
  for (double p : bg.pressure_pa) mean += p / static_cast<double>(bg.pressure_pa.size());
  std::vector<double> dev;
  for (double p : bg.pressure_pa) dev.push_back(p - mean);
  const double step_bar = 250.0 / 65536.0, floor_bar = std::sqrt(0.02 * 0.02 + step_bar * step_bar / 12.0);
  const double noise_bar = 1e-5 * std::sqrt(mean_square(dev));
  // Microphones (A-weighted, energy mean): background_noise's 60 dB(A) (the 40 dB pink floor and the 20 dB(A)
  // self-noise add 0.03 dB) against the motored engine.
  const auto level = [](const RunDir& run) {
    double e = 0.0;
    for (std::size_t m = 0; m < run.mic_count; ++m)
      e += weighted_mean_squares(channel(run, m), run.mic_rate_hz, [](double) { return 1.0; }, {})[0] / run.mic_count;
    return db(e);
  };
  std::printf(
      "background run: pressure %.4f bar +- %.4f bar rms (floor %.4f and 0.1 in quadrature: %.4f); microphones "
      "%.2f dB(A), the motored engine %.2f dB(A)\n",
      1e-5 * mean, noise_bar, floor_bar, std::hypot(floor_bar, 0.1), level(bg), level(mot));
  EXPECT_NEAR(1e-5 * mean, 1.0, 0.01);
  EXPECT_NEAR(noise_bar / std::hypot(floor_bar, 0.1), 1.0, 0.05);
  EXPECT_NEAR(level(bg), 60.0, 0.5);
  EXPECT_GT(level(mot) - level(bg), 20.0);
  ASSERT_TRUE(bg.pressure_noise_floor_bar.has_value());
  EXPECT_NEAR(*bg.pressure_noise_floor_bar, floor_bar, 1e-12);
  // The diagnosis loader: a background condition beside the motored reference.
  const auto data = noisemon::cli::make_band_dataset(noisemon::cli::load_recordings(
      {(base / "runs" / "background").string(), (base / "runs" / "motored_idle").string()}));
  ASSERT_EQ(data.conditions.size(), 2u);
  for (const auto& c : data.conditions) {
    EXPECT_EQ(c.info.background, c.info.name == "background") << c.info.name;
    EXPECT_GE(c.cycles.size(), 1u) << c.info.name;  // measured cycles (after the dataset's pre-roll)
  }
  // truth.json: every setting of the cell, the background run marked.
  const auto truth = nlohmann::json::parse(noisemon::test::slurp(base / "runs" / "truth.json"));
  const auto& cell = truth.at("test_cell");
  EXPECT_EQ(cell.at("pressure_chain").at("noise_bar"), 0.02);
  EXPECT_EQ(cell.at("pressure_chain").at("adc_bits"), 16);
  EXPECT_NEAR(cell.at("pressure_chain").at("floor_bar").get<double>(), floor_bar, 1e-12);
  EXPECT_EQ(cell.at("mic_chain").at("self_noise_dba"), 20.0);
  EXPECT_EQ(cell.at("mic_chain").at("directivity_db"), 1.0);
  EXPECT_EQ(cell.at("mic_chain").at("adc_bits"), 24);
  EXPECT_EQ(cell.at("gas_ringing").at("gain_us"), 6.0);
  EXPECT_EQ(truth.at("adc_clipped").at("pressure_samples"), 0);
  EXPECT_EQ(truth.at("adc_clipped").at("mic_samples"), 0);
  bool marked = false;
  for (const auto& run : truth.at("runs"))
    marked = marked || (run.at("dir") == "background" && run.at("background") == true);
  EXPECT_TRUE(marked);
  // --ideal-cell: every part off, recorded as such.
  const Result ideal = run_noisemon({"sim", "--condition", "idle_mi12", "--ideal-cell", "--cycles", "1",
                                     "--no-progress", "-o", (base / "ideal").string()});
  ASSERT_EQ(ideal.status, 0) << ideal.err;
  const auto ideal_truth = nlohmann::json::parse(noisemon::test::slurp(base / "ideal" / "truth.json"));
  EXPECT_EQ(ideal_truth.at("test_cell").at("ideal_cell"), true);
  EXPECT_EQ(ideal_truth.at("test_cell").at("pressure_chain").at("floor_bar"), 0.0);
  EXPECT_TRUE(ideal_truth.at("test_cell").at("mic_chain").at("self_noise_dba").is_null());
  EXPECT_EQ(ideal_truth.at("test_cell").at("gas_ringing").at("gain_us"), 0.0);
  // The loudest thesis condition does not clip the default microphone range; a clipping run says so.
  const Result loud = run_noisemon(
      {"sim", "--condition", "full_mi24", "--cycles", "2", "--no-progress", "-o", (base / "loud").string()});
  ASSERT_EQ(loud.status, 0) << loud.err;
  EXPECT_EQ(
      nlohmann::json::parse(noisemon::test::slurp(base / "loud" / "truth.json")).at("adc_clipped").at("mic_samples"),
      0);
  EXPECT_EQ(loud.err.find("clipped"), std::string::npos) << loud.err;
}
