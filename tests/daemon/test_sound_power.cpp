// Sound power as ISO 3744:2010 computes it, through the cycle processor: the background correction K1 against the
// same tones measured without the background, the bands too close to the background bounded (K1 1.3 dB), the band
// range (100 Hz ... 10 kHz or all), the meteorological C1 and C2, K2 from the room's
// absorption area, area weights for microphones that are not equal-area; and the set-up against closed forms.
// References: white noise's band level sigma^2 * bandwidth / (fs / 2); eq. 4.1 and the IEC 61672-1 A-weighting
// formula written out here; ISO 3744 eq. 16 (K1) and A.2 (K2) evaluated by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <vector>

#include "daemon/background_run.hpp"
#include "daemon/cycle_processor.hpp"
#include "daemon/sound_power_setup.hpp"
#include "drivers/formats/run_dir.hpp"
#include "drivers/mic_positions.hpp"
#include "dsp/math_constants.hpp"
#include "dsp/sound_power.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon;

namespace {

constexpr double kFs = 40000.0;
using noisemon::kPi;
constexpr int kPowerCycleFrames = 1600;  // 3000 rpm
constexpr int kDelayFrames = 200;
constexpr std::uint32_t kMics = 6;
constexpr double kNoiseSigmaPa = 0.02;  // white background noise at each microphone

std::complex<double> eq_4_1(double f) {
  const double ka = 11.885, wb = 2 * kPi * 100, zeta = 0.35, wn = 2 * kPi * 5000;
  const std::complex<double> s(0, 2 * kPi * f);
  return ka * (s + wb) / (s * s + 2 * zeta * wn * s + wn * wn);
}

double a_weight(double f) {
  const double f1 = 20.598997, f2 = 107.65265, f3 = 737.86223, f4 = 12194.217, f2s = f * f;
  const double ra =
      f4 * f4 * f2s * f2s / ((f2s + f1 * f1) * std::sqrt((f2s + f2 * f2) * (f2s + f3 * f3)) * (f2s + f4 * f4));
  return 20 * std::log10(ra) + 2.000;
}

double level_of_ms(double ms) { return 10 * std::log10(ms / 4e-10); }
double exact_mid(double nominal) { return 1000 * std::pow(10.0, std::round(10 * std::log10(nominal / 1000)) / 10); }
// White noise of variance sigma^2 sampled at fs: its level in the band around `nominal`.
double noise_band_db(double nominal, double sigma, double fs) {
  const double mid = exact_mid(nominal), width = mid * (std::pow(10.0, 0.05) - std::pow(10.0, -0.05));
  return level_of_ms(sigma * sigma * width / (fs / 2));
}

struct Tone {
  double f, mic_amplitude_pa;  // the tone as the microphones hear it
};

struct Result {
  std::vector<daemon::CycleReport> reports;
  std::vector<dsp::ThirdOctaveBand> bands;
  std::size_t band(double nominal) const {
    for (std::size_t b = 0; b < bands.size(); ++b)
      if (bands[b].nominal_hz == nominal) return b;
    ADD_FAILURE() << "no band " << nominal;
    return 0;
  }
};

// Tones in the cylinder pressure whose eq. 4.1 response reaches every microphone, plus (sigma > 0) independent white
// noise at each microphone: the prediction hears the tones only.
Result run(const std::vector<Tone>& tones, double noise_sigma, const daemon::SoundPowerConfig& sp, double seconds = 1.0,
           std::vector<std::array<double, 3>> positions = {}, std::vector<double> gains = {},
           bool time_average = false) {
  drivers::StreamInfo info;
  info.mic_count = !positions.empty() ? static_cast<std::uint32_t>(positions.size())
                   : !gains.empty()   ? static_cast<std::uint32_t>(gains.size())
                                      : kMics;
  info.mic_positions_m = positions;
  info.radius_m = 1.75;
  info.acoustic_delay_s = kDelayFrames / kFs;
  if (gains.empty()) gains.assign(info.mic_count, 1.0);
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  pc.sound_power = sp;
  pc.time_average_mics = time_average;
  Result out;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { out.reports.push_back(r); });
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, noise_sigma > 0 ? noise_sigma : 1.0);
  drivers::SampleBlock pb, mb;
  for (std::int64_t b = 0; b * 256 < static_cast<std::int64_t>(seconds * kFs); ++b) {
    pb.first_index = mb.first_index = b * 256;
    pb.frames = mb.frames = 256;
    pb.channels = drivers::kPressureStreamChannels;
    mb.channels = info.mic_count;
    for (int f = 0; f < 256; ++f) {
      const std::int64_t k = b * 256 + f;
      double pressure = 1e5, sound = 0;
      for (const Tone& t : tones) {
        const std::complex<double> h = eq_4_1(t.f);
        pressure += t.mic_amplitude_pa / std::abs(h) * std::sin(2 * kPi * t.f * k / kFs);
        sound += t.mic_amplitude_pa * std::sin(2 * kPi * t.f * (k - kDelayFrames) / kFs + std::arg(h));
      }
      pb.data[f * 2 + drivers::kPressureChannel] = pressure;
      pb.data[f * 2 + drivers::kCrankChannel] =
          -360.0 + 720.0 * static_cast<double>(k % kPowerCycleFrames) / kPowerCycleFrames;
      for (std::uint32_t m = 0; m < info.mic_count; ++m)
        mb.data[f * info.mic_count + m] = gains[m] * sound + (noise_sigma > 0 ? noise(rng) : 0.0);
    }
    p.add_pressure(pb);
    p.add_mics(mb);
    p.process();
  }
  out.bands = p.bands();
  return out;
}

// The background as a configured spectrum: white noise's band levels at 40 kHz, every band.
daemon::SoundPowerConfig white_background(double sigma) {
  daemon::SoundPowerConfig sp;
  for (int i = 0; i < daemon::kBackgroundBands; ++i)
    sp.background_db.push_back(noise_band_db(daemon::background_band_hz(i), sigma, kFs));
  return sp;
}

// Mean over the settled cycles (from cycle 8 on) of f(report).
template <class F>
double settled_mean(const Result& r, F f) {
  double sum = 0;
  int n = 0;
  for (const auto& c : r.reports)
    if (c.cycle >= 8) sum += f(c), ++n;
  return n > 0 ? sum / n : NAN;
}

// Tones `over_db` above the background in their bands (default: 20, 8 and 0 dB in the 2, 5 and 8 kHz bands).
std::vector<Tone> tones_over(double sigma, std::vector<std::pair<double, double>> nominal_over_db = {
                                               {2000.0, 20.0}, {5000.0, 8.0}, {8000.0, 0.0}}) {
  std::vector<Tone> t;
  for (auto [nominal, over_db] : nominal_over_db) {
    const double ms = std::pow(10.0, (noise_band_db(nominal, sigma, kFs) + over_db) / 10) * 4e-10;
    t.push_back({exact_mid(nominal), std::sqrt(2 * ms)});
  }
  return t;
}

}  // namespace

// ISO 3744:2010's meteorological corrections at the default air (23.0 deg C, 101.325 kPa), by hand.
constexpr double kC1C2Db = -0.1271 + 0.0033;  // 5 lg(296.15 / 314) + 15 lg(296.15 / 296)

TEST(SoundPower, BackgroundCorrectionRecoversTheSourceAloneAndBoundsBandsTooCloseToTheBackground) {
  const std::vector<Tone> tones = tones_over(kNoiseSigmaPa);
  const Result noisy = run(tones, kNoiseSigmaPa, white_background(kNoiseSigmaPa));
  const Result clean = run(tones, 0.0, {});
  ASSERT_GE(noisy.reports.size(), 20u);
  const std::size_t b2k = noisy.band(2000), b5k = noisy.band(5000), b8k = noisy.band(8000), b500 = noisy.band(500);
  const auto unweighted = [&](const daemon::CycleReport& c, std::size_t b) {
    return c.spl_a_measured_db[b] - a_weight(noisy.bands[b].exact_mid_hz);
  };
  // 2 kHz: 20 dB above the background, no correction (ISO 3744:2010: over 15 dB).
  EXPECT_NEAR(settled_mean(noisy, [&](const auto& c) { return c.k1_db[b2k]; }), 0.0, 1e-9);
  // 5 kHz: 8 dB above, corrected: the band less K1 is the tone alone (the background adds 0.75 dB).
  const double tone_5k = settled_mean(clean, [&](const auto& c) { return unweighted(c, b5k); });
  EXPECT_GT(settled_mean(noisy, [&](const auto& c) { return unweighted(c, b5k); }) - tone_5k, 0.5);
  EXPECT_NEAR(settled_mean(noisy, [&](const auto& c) { return unweighted(c, b5k) - c.k1_db[b5k]; }), tone_5k, 0.25);
  EXPECT_NEAR(settled_mean(noisy, [&](const auto& c) { return c.k1_db[b5k]; }),
              -10 * std::log10(1 - std::pow(10, -0.8)), 0.3);
  for (const auto& c : noisy.reports) {
    if (c.cycle < 8) continue;
    EXPECT_EQ(c.band_flags[b2k] & daemon::kBandBackground, 0);
    EXPECT_EQ(c.band_flags[b5k] & daemon::kBandBackground, 0);
    // 8 kHz: the tone doubles the background (3 dB), 500 Hz holds only the background: K1 1.3 dB, an upper bound.
    EXPECT_NE(c.band_flags[b8k] & daemon::kBandBackground, 0) << c.cycle;
    EXPECT_NE(c.band_flags[b500] & daemon::kBandBackground, 0) << c.cycle;
    EXPECT_EQ(c.k1_db[b8k], 1.3f);
    EXPECT_NE(c.flags & daemon::kCycleLwUpperBound, 0) << c.cycle;
  }
  // LW(A) over 100 Hz ... 10 kHz: the 2 and 5 kHz tones alone; every other band, background only (its white-noise
  // level; twice it at 8 kHz, where the tone equals it), less 1.3 dB; plus 10 lg(2 pi r^2), C1 and C2.
  double tones_and_bounds =
      std::pow(10, settled_mean(clean, [&](const auto& c) { return c.spl_a_measured_db[b2k]; }) / 10) +
      std::pow(10, (tone_5k + a_weight(noisy.bands[b5k].exact_mid_hz)) / 10);
  double tones_only = tones_and_bounds;
  for (const dsp::ThirdOctaveBand& band : noisy.bands) {
    if (band.nominal_hz < 100 || band.nominal_hz > 10000 || band.nominal_hz == 2000 || band.nominal_hz == 5000)
      continue;
    const double background =
        noise_band_db(band.nominal_hz, kNoiseSigmaPa, kFs) + (band.nominal_hz == 8000 ? 10 * std::log10(2.0) : 0.0);
    tones_and_bounds += std::pow(10, (background + a_weight(band.exact_mid_hz) - 1.3) / 10);
    if (band.nominal_hz == 8000)
      tones_only += std::pow(10, (background - 10 * std::log10(2.0) + a_weight(band.exact_mid_hz)) / 10);
  }
  const double surface = 10 * std::log10(2 * kPi * 1.75 * 1.75);
  EXPECT_NEAR(settled_mean(noisy, [](const auto& c) { return c.lwa_measured_db; }),
              10 * std::log10(tones_and_bounds) + surface + kC1C2Db, 0.2);
  // The prediction hears the tones only, the 8 kHz one included; no K1 applies to it.
  EXPECT_NEAR(settled_mean(noisy, [](const auto& c) { return c.lwa_predicted_db; }),
              10 * std::log10(tones_only) + surface + kC1C2Db, 0.2);
  // Lp(A) stays what the microphones heard: the background is in it.
  EXPECT_GT(settled_mean(noisy, [](const auto& c) { return c.lpa_measured_db; }),
            settled_mean(clean, [](const auto& c) { return c.lpa_measured_db; }) + 0.5);
}

TEST(SoundPower, LwOverTheStandardsBandsByDefaultAndEveryBandWhenAsked) {
  // A 63 Hz and a 12.5 kHz tone outside ISO 3744's 100 Hz ... 10 kHz, a 1 kHz tone inside; no background.
  const std::vector<Tone> tones{{exact_mid(63.0), 0.5}, {exact_mid(1000.0), 0.5}, {exact_mid(12500.0), 0.5}};
  daemon::SoundPowerConfig sp;
  const Result standard = run(tones, 0.0, sp);
  sp.full_range = true;
  const Result full = run(tones, 0.0, sp);
  const double surface = 10 * std::log10(2 * kPi * 1.75 * 1.75), ms = 0.5 * 0.5 / 2;
  const auto tone_a = [&](double nominal) { return level_of_ms(ms) + a_weight(exact_mid(nominal)); };
  const double inside = tone_a(1000);
  const double all =
      10 * std::log10(std::pow(10, tone_a(63) / 10) + std::pow(10, inside / 10) + std::pow(10, tone_a(12500) / 10));
  EXPECT_NEAR(settled_mean(standard, [](const auto& c) { return c.lwa_measured_db; }), inside + surface + kC1C2Db, 0.1);
  EXPECT_NEAR(settled_mean(full, [](const auto& c) { return c.lwa_measured_db; }), all + surface + kC1C2Db, 0.1);
  EXPECT_EQ(standard.reports.back().lw_low_hz, 100.f);
  EXPECT_EQ(standard.reports.back().lw_high_hz, 10000.f);
  // Lp(A) covers every band of the overall levels either way.
  EXPECT_NEAR(settled_mean(standard, [](const auto& c) { return c.lpa_measured_db; }), all, 0.1);
  // Air at 35 deg C and 92 kPa: C1 + C2 = -20 lg(92 / 101.325) + 5 lg(308.15 / 314) + 15 lg(308.15 / 296).
  sp.full_range = false;
  sp.air_temperature_c = 35.0;
  sp.air_pressure_kpa = 92.0;
  const Result hot = run(tones, 0.0, sp);
  const double c = -20 * std::log10(92.0 / 101.325) + 5 * std::log10(308.15 / 314.0) + 15 * std::log10(308.15 / 296.0);
  EXPECT_NEAR(settled_mean(hot, [](const auto& c) { return c.lwa_measured_db; }), inside + surface + c, 0.1);
  EXPECT_NEAR(hot.reports.back().c1_db + hot.reports.back().c2_db, c, 1e-9);
}

TEST(SoundPower, EnvironmentalCorrectionK2FromTheAbsorptionAreaLowersBothSoundPowers) {
  const std::vector<Tone> tones{{1000.0, 0.5}};
  daemon::SoundPowerConfig sp;
  const Result free_field = run(tones, 0.0, sp, 0.5);
  sp.absorption_area_m2 = 4 * 2 * kPi * 1.75 * 1.75;  // A = 4 S: K2 = 10 lg 2
  const Result room = run(tones, 0.0, sp, 0.5);
  ASSERT_EQ(free_field.reports.size(), room.reports.size());
  for (std::size_t i = 0; i < room.reports.size(); ++i) {
    EXPECT_NEAR(room.reports[i].k2_db, 10 * std::log10(2.0), 1e-12);
    EXPECT_NEAR(free_field.reports[i].lwa_measured_db - room.reports[i].lwa_measured_db, 10 * std::log10(2.0), 1e-9);
    EXPECT_NEAR(free_field.reports[i].lwa_predicted_db - room.reports[i].lwa_predicted_db, 10 * std::log10(2.0), 1e-9);
    EXPECT_DOUBLE_EQ(free_field.reports[i].lpa_measured_db, room.reports[i].lpa_measured_db);
  }
}

TEST(SoundPower, MicrophonesThatAreNotEqualAreaAreWeightedByTheirShareOfTheHemisphere) {
  // Three at the rim 120 deg apart and one at the top: the top one stands for less of the surface.
  const double r = 1.75, z = 0.2 * r, rho = std::sqrt(r * r - z * z);
  std::vector<std::array<double, 3>> positions{{0, 0, r}};
  for (int i = 0; i < 3; ++i)
    positions.push_back({rho * std::cos(2 * kPi * i / 3), rho * std::sin(2 * kPi * i / 3), z});
  const std::vector<double> gains{2.0, 1.0, 1.0, 1.0};  // the top microphone hears 6 dB more
  daemon::SoundPowerConfig sp;
  sp.voronoi_area_weights = true;
  const Result res = run({{1000.0, 0.5}}, 0.0, sp, 0.5, positions, gains);
  const Result equal = run({{1000.0, 0.5}}, 0.0, {}, 0.5, positions, gains);
  const std::vector<double> shares = dsp::hemisphere_area_weights(positions);
  ASSERT_GT(std::abs(shares[0] - 0.25), 0.03);  // far from the 1/4 of an equal split
  double weighted = 0;
  for (std::size_t m = 0; m < 4; ++m) weighted += shares[m] * gains[m] * gains[m];
  const std::size_t b1k = res.band(1000);
  const double tone_db = level_of_ms(0.5 * 0.5 / 2) + a_weight(res.bands[b1k].exact_mid_hz);
  for (const auto& c : res.reports)
    if (c.cycle >= 5) {
      EXPECT_NEAR(c.spl_a_measured_db[b1k], tone_db + 10 * std::log10(weighted), 0.15);
    }
  // By default the shares are equal: the plain energy mean, (4 + 1 + 1 + 1) / 4.
  for (const auto& c : equal.reports)
    if (c.cycle >= 5) {
      EXPECT_NEAR(c.spl_a_measured_db[b1k], tone_db + 10 * std::log10(7.0 / 4), 0.15);
    }
}

TEST(SoundPower, ConfiguredSharesMustMatchTheMicrophones) {
  daemon::SoundPowerConfig sp;
  sp.area_weights = {1, 2, 3};
  EXPECT_THROW(run({{1000.0, 0.5}}, 0.0, sp, 0.1), std::invalid_argument);
  sp.area_weights = {1, 1, 1, 1, 1, 5};  // the last microphone stands for half the surface
  const Result res = run({{1000.0, 0.5}}, 0.0, sp, 0.3, {}, {1, 1, 1, 1, 1, 2});
  const std::size_t b1k = res.band(1000);
  const double tone_db = level_of_ms(0.5 * 0.5 / 2) + a_weight(res.bands[b1k].exact_mid_hz);
  for (const auto& c : res.reports)
    if (c.cycle >= 5) {
      EXPECT_NEAR(c.spl_a_measured_db[b1k], tone_db + 10 * std::log10(0.5 * 1 + 0.5 * 4), 0.15);
    }
}

TEST(SoundPowerSetup, PresetPositionsAreEqualAreaAndOnTheirHemisphere) {
  for (const auto& positions : {drivers::thesis_mic_positions(), dsp::iso3744_key_positions(1.75)}) {
    drivers::StreamInfo info;
    info.mic_count = 10;
    info.mic_positions_m = positions;
    info.radius_m = 1.75;
    const daemon::SoundPowerSetup setup({}, info, {});
    for (double w : setup.area_weights()) EXPECT_DOUBLE_EQ(w, 0.1);
    EXPECT_TRUE(setup.problems().empty()) << setup.problems().front();
    EXPECT_NEAR(setup.surface_term_db(), 10 * std::log10(2 * kPi * 1.75 * 1.75), 1e-12);
  }
}

TEST(SoundPowerSetup, NamesTheMicrophoneOffTheHemisphereAndTheSurfaceTooSmall) {
  drivers::StreamInfo info;
  info.mic_count = 10;
  info.mic_positions_m = drivers::thesis_mic_positions();
  info.mic_positions_m[3] = {0.5, 0.5, 0.9};  // 1.15 m from the centre
  info.radius_m = 1.75;
  daemon::SoundPowerConfig sp;
  sp.source_dimension_m = 1.0;  // the radius must be at least 2 m
  const std::vector<std::string> problems = daemon::SoundPowerSetup(sp, info, {}).problems();
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_NE(problems[0].find("twice the source's dimension"), std::string::npos) << problems[0];
  EXPECT_EQ(problems[1].rfind("mic4: ", 0), 0u) << problems[1];
}

TEST(SoundPowerSetup, BackgroundRunGivesTheWhiteNoiseBandLevels) {
  drivers::formats::RunDir run;
  run.condition.name = "background";
  run.condition.speed_rpm = NAN;  // the engine is off: null in run.json
  for (int i = 0; i < 20; ++i) {  // a few rows of a resting engine: the background ignores them
    run.time_s.push_back(i * 1e-3);
    run.crank_deg.push_back(i * 0.2);
    run.pressure_pa.push_back(1e5);
  }
  const double fs = 48000, sigma = 0.05;
  run.mic_rate_hz = fs;
  run.mic_count = 2;
  run.mic_positions_m = {{1.75, 0, 0}, {0, 1.75, 0}};
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, sigma);
  for (int k = 0; k < 2 * 8 * static_cast<int>(fs); ++k) run.mic_pa.push_back(static_cast<float>(noise(rng)));
  const std::filesystem::path dir = test::unique_temp("background");
  drivers::formats::write_run_dir(dir, run);
  const std::vector<double> levels = daemon::background_from_run_dir(dir);
  ASSERT_EQ(levels.size(), static_cast<std::size_t>(daemon::kBackgroundBands));
  for (int i = 0; i < daemon::kBackgroundBands; ++i) {
    const double nominal = daemon::background_band_hz(i);
    if (nominal < 100) continue;
    // A noise band level's spread: 4.34 dB / sqrt(bandwidth x duration x microphones); three of them, plus 0.1 dB
    // for the filters' noise bandwidths.
    const double dof = 0.23 * exact_mid(nominal) * 8.0 * 2;
    EXPECT_NEAR(levels[i], noise_band_db(nominal, sigma, fs), 0.1 + 3 * 4.34 / std::sqrt(dof)) << nominal << " Hz";
  }
}

TEST(SoundPowerSetup, BackgroundRunWithoutMicrophonesIsRefusedNamingTheFile) {
  drivers::formats::RunDir run;
  run.condition.name = "no mics";
  run.condition.speed_rpm = NAN;
  for (int i = 0; i < 20; ++i) {
    run.time_s.push_back(i * 1e-3);
    run.crank_deg.push_back(i * 0.2);
    run.pressure_pa.push_back(1e5);
  }
  const std::filesystem::path dir = test::unique_temp("nomics");
  drivers::formats::write_run_dir(dir, run);
  try {
    daemon::background_from_run_dir(dir);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "run.json").string()), std::string::npos) << e.what();
  }
}

// The thesis's averaging: the band level of the microphones' mean time history. Two microphones hear the same tone,
// one at half the amplitude and inverted: the energy mean is (1 + 1/4) / 2 of the tone's power (-2.04 dB), the time
// mean ((1 - 1/2) / 2)^2 of it (-12.04 dB). Uncorrelated noise at six microphones: the time mean keeps 1/6 of it.
TEST(MicAverage, TimeMeanCancelsWhatDiffersInPhaseAndEnergyMeanDoesNot) {
  const std::vector<Tone> tone{{1000.0, 0.5}};
  const Result energy = run(tone, 0.0, {}, 0.5, {}, {1.0, -0.5});
  const Result time = run(tone, 0.0, {}, 0.5, {}, {1.0, -0.5}, true);
  const std::size_t b1k = energy.band(1000);
  const double tone_db = level_of_ms(0.5 * 0.5 / 2) + a_weight(energy.bands[b1k].exact_mid_hz);
  EXPECT_NEAR(settled_mean(energy, [&](const auto& c) { return c.spl_a_measured_db[b1k]; }),
              tone_db + 10 * std::log10(0.625), 0.15);
  EXPECT_NEAR(settled_mean(time, [&](const auto& c) { return c.spl_a_measured_db[b1k]; }),
              tone_db + 20 * std::log10(0.25), 0.15);
  // The prediction does not depend on how the microphones are averaged.
  EXPECT_DOUBLE_EQ(settled_mean(energy, [](const auto& c) { return c.lpa_predicted_db; }),
                   settled_mean(time, [](const auto& c) { return c.lpa_predicted_db; }));
  const Result noise_energy = run({}, kNoiseSigmaPa, {}, 0.5);
  const Result noise_time = run({}, kNoiseSigmaPa, {}, 0.5, {}, {}, true);
  const std::size_t b4k = noise_energy.band(4000);
  EXPECT_NEAR(settled_mean(noise_energy, [&](const auto& c) { return c.spl_a_measured_db[b4k]; }) -
                  settled_mean(noise_time, [&](const auto& c) { return c.spl_a_measured_db[b4k]; }),
              10 * std::log10(6.0), 0.5);
}
