// CycleProcessor against analytic references: streams synthesised from tones whose band levels and whose
// response through eq. 4.1 are known in closed form; microphones delayed by the acoustic delay.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>
#include <numbers>
#include <vector>

#include "daemon/cycle_processor.hpp"
#include "daemon/report_messages.hpp"

using namespace noisemon;

namespace {

constexpr double kFs = 40000.0;
constexpr double kPi = std::numbers::pi;
constexpr int kCycleFrames = 1600;  // 0.04 s per 720 deg: 3000 rpm
constexpr int kDelayFrames = 200;   // 5 ms acoustic delay
constexpr std::uint32_t kMics = 3;

// Eq. 4.1 written out from the thesis constants (independent of model/).
std::complex<double> eq_4_1(double f) {
  const double ka = 11.885, wb = 2 * kPi * 100, zeta = 0.35, wn = 2 * kPi * 5000;
  const std::complex<double> s(0, 2 * kPi * f);
  return ka * (s + wb) / (s * s + 2 * zeta * wn * s + wn * wn);
}

// IEC 61672-1 A-weighting at the exact mid-band frequencies used below (from the standard's formula).
double a_weight(double f) {
  const double f1 = 20.598997, f2 = 107.65265, f3 = 737.86223, f4 = 12194.217;
  const double f2s = f * f;
  const double ra = f4 * f4 * f2s * f2s / ((f2s + f1 * f1) * std::sqrt((f2s + f2 * f2) * (f2s + f3 * f3)) * (f2s + f4 * f4));
  return 20 * std::log10(ra) + 2.000;
}

double level(double amplitude) { return 20 * std::log10(amplitude / std::sqrt(2.0) / 20e-6); }

struct Tone {
  double f, amplitude;
  bool gated;  // present only in even cycles (smoothly switched inside the cycle)
};

// Gate: 1 inside even cycles, with raised-cosine ramps well inside the cycle, 0 in odd cycles.
double gate(std::int64_t k) {
  const std::int64_t c = k / kCycleFrames;
  if (c % 2) return 0.0;
  const double x = static_cast<double>(k % kCycleFrames) / kCycleFrames;
  const double ramp = 0.1;
  if (x < ramp) return 0.5 - 0.5 * std::cos(kPi * x / ramp);
  if (x > 1 - ramp) return 0.5 - 0.5 * std::cos(kPi * (1 - x) / ramp);
  return 1.0;
}

class Synth {
 public:
  explicit Synth(std::vector<Tone> tones) : tones_(std::move(tones)) {}
  double pressure(std::int64_t k) const {
    double p = 1e5;
    for (const Tone& t : tones_) p += (t.gated ? gate(k) : 1.0) * t.amplitude * std::sin(2 * kPi * t.f * k / kFs);
    return p;
  }
  // Microphone m at frame k hears the block output of frame k - delay (steady-state tone response).
  double mic(std::int64_t k, std::uint32_t m) const {
    const std::int64_t src = k - kDelayFrames;
    double y = 0;
    for (const Tone& t : tones_) {
      const std::complex<double> h = eq_4_1(t.f);
      const double g = t.gated ? (src >= 0 ? gate(src) : 0.0) : 1.0;
      y += g * t.amplitude * std::abs(h) * std::sin(2 * kPi * t.f * src / kFs + std::arg(h));
    }
    return gain(m) * y;
  }
  // Gains whose mean square is exactly 1: the energy average equals the block output.
  static double gain(std::uint32_t m) {
    static const double g[kMics] = {std::sqrt(0.8), std::sqrt(1.0), std::sqrt(1.2)};
    return g[m];
  }

 private:
  std::vector<Tone> tones_;
};

double crank(std::int64_t k) { return -360.0 + 720.0 * static_cast<double>(k % kCycleFrames) / kCycleFrames; }

struct RunResult {
  std::vector<daemon::CycleReport> reports;
  daemon::ProcessorCounters counters;
  std::vector<dsp::ThirdOctaveBand> bands;
};

// Which blocks reach the processor: (microphone stream?, block number) -> delivered?
using Delivery = std::function<bool(bool, std::int64_t)>;

// Feeds `seconds` of synthetic streams in 256-frame blocks; `drop_mic_block` (>= 0) is lost on the way, and so is
// every block `deliver` refuses.
RunResult run(const Synth& s, double seconds, std::int64_t drop_mic_block = -1, const Delivery& deliver = {},
              double fifo_seconds = 4.0) {
  drivers::StreamInfo info;
  info.epoch_utime = 1'000'000;
  info.mic_count = kMics;
  info.radius_m = 1.75;
  info.acoustic_delay_s = kDelayFrames / kFs;
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  pc.fifo_seconds = fifo_seconds;
  RunResult out;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { out.reports.push_back(r); });
  const std::int64_t total = static_cast<std::int64_t>(seconds * kFs);
  drivers::SampleBlock pb, mb;
  for (std::int64_t b = 0; b * 256 < total; ++b) {
    pb.first_index = mb.first_index = b * 256;
    pb.frames = mb.frames = 256;
    pb.channels = drivers::kPressureStreamChannels;
    mb.channels = kMics;
    for (int f = 0; f < 256; ++f) {
      const std::int64_t k = b * 256 + f;
      pb.data[f * 2 + drivers::kPressureChannel] = s.pressure(k);
      pb.data[f * 2 + drivers::kCrankChannel] = crank(k);
      for (std::uint32_t m = 0; m < kMics; ++m) mb.data[f * kMics + m] = s.mic(k, m);
    }
    if (!deliver || deliver(false, b)) p.add_pressure(pb);
    if (b != drop_mic_block && (!deliver || deliver(true, b))) p.add_mics(mb);
    p.process();
  }
  out.counters = p.counters();
  out.bands = p.bands();
  return out;
}

std::size_t band_index(const std::vector<dsp::ThirdOctaveBand>& bands, double nominal) {
  for (std::size_t i = 0; i < bands.size(); ++i)
    if (bands[i].nominal_hz == nominal) return i;
  ADD_FAILURE() << "no band " << nominal;
  return 0;
}

}  // namespace

TEST(CycleProcessor, SteadyTonesMatchAnalyticLevels) {
  const Synth s({{1000.0, 2000.0, false}, {5000.0, 300.0, false}});
  const RunResult r = run(s, 1.2);
  // Cycles start at frames 1600, 3200, ...; the last is complete once its microphone window has arrived.
  ASSERT_GE(r.reports.size(), 25u);
  const std::size_t b1k = band_index(r.bands, 1000), b5k = band_index(r.bands, 5000);
  for (const auto& c : r.reports) {
    EXPECT_NEAR(c.duration_s, kCycleFrames / kFs, 1e-9);
    EXPECT_NEAR(c.op.speed_rpm, 3000.0, 1e-6);
    EXPECT_EQ(c.nmics, kMics);
    if (c.cycle < 5) continue;  // let the filters settle
    // Cylinder pressure level of each tone.
    EXPECT_NEAR(c.cpl_db[b1k], level(2000.0), 0.15);
    EXPECT_NEAR(c.cpl_db[b5k], level(300.0), 0.15);
    // Predicted and measured A-weighted band levels: tone through eq. 4.1, then A-weighting.
    for (auto [b, f, a] : {std::tuple{b1k, 1000.0, 2000.0}, std::tuple{b5k, 5000.0, 300.0}}) {
      const double expected = level(a * std::abs(eq_4_1(f))) + a_weight(r.bands[b].exact_mid_hz);
      EXPECT_NEAR(c.spl_a_predicted_db[b], expected, 0.15) << "band " << f;
      EXPECT_NEAR(c.spl_a_measured_db[b], expected, 0.15) << "band " << f;
      EXPECT_NEAR(c.att_measured_db[b], c.cpl_db[b] - expected, 0.2);
    }
    // Overall Lp(A): the energy sum of both tones' A-weighted levels; LW(A) adds 10 log10(2 pi r^2).
    const double expected_lpa =
        10 * std::log10(std::pow(10, (level(2000 * std::abs(eq_4_1(1000))) + a_weight(r.bands[b1k].exact_mid_hz)) / 10) +
                        std::pow(10, (level(300 * std::abs(eq_4_1(5000))) + a_weight(r.bands[b5k].exact_mid_hz)) / 10));
    EXPECT_NEAR(c.lpa_measured_db, expected_lpa, 0.2);
    EXPECT_NEAR(c.lpa_predicted_db, expected_lpa, 0.2);
    EXPECT_NEAR(c.lwa_measured_db - c.lpa_measured_db, 10 * std::log10(2 * kPi * 1.75 * 1.75), 1e-9);
    // Per-microphone levels follow the microphone gains (0.8, 1.0, 1.2 in mean square).
    EXPECT_NEAR(c.mic_lpa_db[2] - c.mic_lpa_db[0], 10 * std::log10(1.2 / 0.8), 0.05);
  }
  EXPECT_EQ(r.counters.cycles_dropped, 0);
}

TEST(CycleProcessor, MicrophoneWindowIsShiftedByTheAcousticDelay) {
  // A 5 kHz tone only in even cycles: with the delay removed, the microphones' level in every cycle follows the
  // pressure's. Without the shift 1/8 of the burst would land in the odd cycles (only ~9 dB down).
  const Synth s({{5000.0, 500.0, true}});
  const RunResult r = run(s, 1.2);
  const std::size_t b5k = band_index(r.bands, 5000);
  int even = 0, odd = 0;
  for (const auto& c : r.reports) {
    if (c.cycle < 5) continue;
    // Report cycle n covers source cycle n + 1 (the first boundary is at frame 1600).
    const bool on = (c.cycle + 1) % 2 == 0;
    if (on) {
      ++even;
      EXPECT_NEAR(c.spl_a_measured_db[b5k], c.spl_a_predicted_db[b5k], 0.2);
    } else {
      ++odd;
      // Off cycles: the burst's level is far below the on level in both channels.
      EXPECT_LT(c.spl_a_measured_db[b5k], level(500 * std::abs(eq_4_1(5000))) - 25.0);
    }
  }
  EXPECT_GT(even, 5);
  EXPECT_GT(odd, 5);
}

TEST(CycleProcessor, LostBlockDropsOnlyTheCyclesItTouches) {
  const Synth s({{1000.0, 2000.0, false}});
  const RunResult clean = run(s, 1.2);
  const RunResult lossy = run(s, 1.2, 60);  // frames 15360..15615 of the microphones are lost
  EXPECT_GE(lossy.counters.cycles_dropped, 1);
  EXPECT_LE(lossy.counters.cycles_dropped, 2);
  EXPECT_EQ(lossy.counters.gap_frames, 256);
  EXPECT_EQ(lossy.reports.size() + static_cast<std::size_t>(lossy.counters.cycles_dropped), clean.reports.size());
  // Published cycles keep their index; the dropped index is missing.
  for (const auto& c : lossy.reports) {
    const std::int64_t first = c.cycle * kCycleFrames + kCycleFrames;
    EXPECT_FALSE(first <= 15360 - kDelayFrames + 256 && first + kCycleFrames > 15360 - kDelayFrames) << c.cycle;
  }
}

TEST(CycleProcessor, PressureOnlyStreamReportsCplAndPredictionsAndSaysNothingWasMeasured) {
  // No microphones (an imported cycle table): the same tones as above, pressure stream only.
  const Synth s({{1000.0, 2000.0, false}, {5000.0, 300.0, false}});
  drivers::StreamInfo info;
  info.epoch_utime = 1'000'000;
  info.mic_count = 0;
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  std::vector<daemon::CycleReport> reports;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { reports.push_back(r); });
  drivers::SampleBlock pb;
  pb.channels = drivers::kPressureStreamChannels;
  pb.frames = 256;
  std::int64_t fed = 0;
  for (std::int64_t b = 0; b * 256 < static_cast<std::int64_t>(1.2 * kFs); ++b, fed += 256) {
    pb.first_index = b * 256;
    for (int f = 0; f < 256; ++f) {
      pb.data[f * 2 + drivers::kPressureChannel] = s.pressure(b * 256 + f);
      pb.data[f * 2 + drivers::kCrankChannel] = crank(b * 256 + f);
    }
    p.add_pressure(pb);
    p.process();
  }
  // A cycle closes at the next crank wrap (frames 1600, 3200, ...). Without microphones there is no acoustic
  // delay to wait for: every wrap inside the fed frames closes a cycle (the model's interpolator lag, a few
  // dozen frames, is below the 128 frames fed after the last wrap at 48000). The first wrap only opens one.
  std::size_t wraps = 0;
  for (std::int64_t k = kCycleFrames; k < fed; k += kCycleFrames) ++wraps;
  ASSERT_EQ(fed % kCycleFrames, 128);  // the premise above
  ASSERT_EQ(reports.size(), wraps - 1);  // 29: [1600, 3200) ... [46400, 48000)
  EXPECT_EQ(reports.front().utime, 1'000'000 + 1600 * 25);  // 25 us per frame at 40 kHz
  EXPECT_EQ(reports.back().utime, 1'000'000 + 46400 * 25);
  const std::size_t b1k = band_index(p.bands(), 1000), b5k = band_index(p.bands(), 5000);
  for (const auto& c : reports) {
    EXPECT_TRUE(c.flags & daemon::kCycleNoMics);
    EXPECT_EQ(c.nmics, 0);
    EXPECT_TRUE(std::isnan(c.lpa_measured_db));
    EXPECT_TRUE(std::isnan(c.lwa_measured_db));
    EXPECT_TRUE(std::isfinite(c.lpa_predicted_db));
    for (std::size_t b = 0; b < c.nbands; ++b) {
      EXPECT_TRUE(std::isnan(c.spl_a_measured_db[b]));
      EXPECT_TRUE(std::isnan(c.att_measured_db[b]));
    }
    if (c.cycle < 5) continue;
    EXPECT_NEAR(c.cpl_db[b1k], level(2000.0), 0.15);
    EXPECT_NEAR(c.cpl_db[b5k], level(300.0), 0.15);
    const double expected = level(300 * std::abs(eq_4_1(5000))) + a_weight(p.bands()[b5k].exact_mid_hz);
    EXPECT_NEAR(c.spl_a_predicted_db[b5k], expected, 0.15);
    EXPECT_NEAR(c.att_predicted_db[b5k], c.cpl_db[b5k] - expected, 0.2);
  }
  // The messages and the text say so: NaN in the message and CSV, "n/a" and "no-mics" on the line.
  const noisemon::cycle_report_t m = daemon::to_message(reports.back());
  EXPECT_TRUE(m.flags & noisemon::cycle_report_t::CYCLE_NO_MICS);
  EXPECT_TRUE(std::isnan(m.lpa_measured_db));
  const std::string line = daemon::cycle_line(m);
  EXPECT_NE(line.find("n/a"), std::string::npos) << line;
  EXPECT_NE(line.find("no-mics"), std::string::npos) << line;
  const std::string row = daemon::cycle_csv_row(m, "motored");
  EXPECT_NE(row.find(",nan,"), std::string::npos) << row;
  EXPECT_EQ(row.substr(row.size() - 9), ",motored\n");
  // A microphone block for a stream without microphones is a usage error, not silently mixed in.
  drivers::SampleBlock mb;
  mb.channels = 1;
  mb.frames = 1;
  EXPECT_THROW(p.add_mics(mb), std::invalid_argument);
}

// One stream stops delivering for 1, 5 and 30 s (a microphone card that stops, a paused encoder-clocked scan) while
// the other keeps flowing, then resumes at the current time: the processor never fails, drops exactly the cycles
// the stall touches, counts what its 4 s FIFOs pushed out, and reports valid cycles again within two cycles.
TEST(CycleProcessor, AStalledStreamDropsTheCyclesItTouchesAndProcessingResumes) {
  const Synth s({{1000.0, 2000.0, false}});
  for (const bool mics_stall : {true, false})
    for (const double stall_s : {1.0, 5.0, 30.0}) {
      SCOPED_TRACE(std::string(mics_stall ? "microphones" : "pressure") + " stalled " + std::to_string(stall_s) + " s");
      const std::int64_t from = 40, to = from + static_cast<std::int64_t>(stall_s * kFs / 256);  // blocks
      const Delivery stall = [&](bool mics, std::int64_t b) { return mics != mics_stall || b < from || b >= to; };
      RunResult r;
      ASSERT_NO_THROW(r = run(s, 1.0 + stall_s + 1.0, -1, stall));
      const std::int64_t gap_from = from * 256, gap_to = to * 256;  // frames of the stalled stream
      const std::int64_t shift = mics_stall ? kDelayFrames : 0;      // microphone frame n + d belongs to combined n
      std::int64_t first_after = INT64_MAX;
      const auto start_of = [](const daemon::CycleReport& c) { return (c.utime - 1'000'000) * 40 / 1000; };  // frames
      for (const auto& c : r.reports) {
        const std::int64_t start = start_of(c);  // combined frame where the report's cycle starts
        EXPECT_FALSE(start < gap_to - shift && start + kCycleFrames > gap_from - shift) << "cycle " << c.cycle << " overlaps the stall";
        if (start >= gap_to - shift) first_after = std::min(first_after, start);
      }
      EXPECT_LE(first_after, gap_to - shift + 2 * kCycleFrames) << "no valid cycle within two cycles of the resumption";
      const std::int64_t stalled_cycles = (gap_to - gap_from) / kCycleFrames;
      EXPECT_GE(r.counters.cycles_dropped, stalled_cycles);
      EXPECT_LE(r.counters.cycles_dropped, stalled_cycles + 2);
      const double held_s = std::exp2(std::ceil(std::log2(4.0 * kFs))) / kFs;  // 4 s rounded up to 2^n frames
      if (stall_s < held_s) {
        EXPECT_EQ(r.counters.frames_discarded, 0);
      } else {
        EXPECT_GT(r.counters.frames_discarded, 0);
      }
      // After the resumption the levels are right again (the first cycles after it included).
      const std::size_t b1k = band_index(r.bands, 1000);
      const double expected_1k = level(2000 * std::abs(eq_4_1(1000))) + a_weight(r.bands[b1k].exact_mid_hz);
      int checked = 0;
      for (const auto& c : r.reports) {
        const std::int64_t start = start_of(c);
        if (start < gap_to - shift || checked >= 5) continue;
        EXPECT_NEAR(c.spl_a_measured_db[b1k], expected_1k, 0.3) << "cycle " << c.cycle;
        EXPECT_NEAR(c.spl_a_predicted_db[b1k], expected_1k, 0.3) << "cycle " << c.cycle;
        ++checked;
      }
      EXPECT_EQ(checked, 5);
    }
}

// The combustion metrics of every cycle come from the 40 kHz pressure put back on a crank-angle grid: on a smooth
// combustion pulse (3000 rpm: 0.45 deg per frame) they match the metrics of the pulse sampled on the grid directly.
TEST(CycleProcessor, CombustionMetricsOfEachCycleMatchThoseOfThePressureOnTheCrankAngleGrid) {
  const auto pulse = [](double theta) { return 1.5e5 + 40e5 * std::exp(-std::pow((theta - 8.0) / 15.0, 2)); };
  drivers::StreamInfo info;
  info.epoch_utime = 1'000'000;
  info.mic_count = 1;
  info.radius_m = 1.75;
  info.acoustic_delay_s = 0;
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  std::vector<daemon::CycleReport> reports;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { reports.push_back(r); });
  drivers::SampleBlock pb, mb;
  for (std::int64_t b = 0; b * 256 < 40000; ++b) {
    pb.first_index = mb.first_index = b * 256;
    pb.frames = mb.frames = 256;
    pb.channels = drivers::kPressureStreamChannels;
    mb.channels = 1;
    for (int f = 0; f < 256; ++f) {
      const std::int64_t k = b * 256 + f;
      pb.data[f * 2 + drivers::kPressureChannel] = pulse(crank(k));
      pb.data[f * 2 + drivers::kCrankChannel] = crank(k);
      mb.data[f] = 0.0;
    }
    p.add_pressure(pb);
    p.add_mics(mb);
    p.process();
  }
  std::vector<double> grid(2881);
  for (std::size_t i = 0; i < grid.size(); ++i) grid[i] = pulse(-360.0 + 0.25 * static_cast<double>(i));
  const model::CombustionMetrics want = model::combustion_metrics(grid, -360.0, 0.25, model::EngineGeometry{}, 3000.0);
  ASSERT_GE(reports.size(), 20u);
  for (const auto& r : reports) {
    const model::CombustionMetrics& got = r.combustion;
    EXPECT_NEAR(got.peak_pressure_pa, 41.5e5, 1e3) << r.cycle;
    EXPECT_NEAR(got.peak_angle_deg, 8.0, 0.02) << r.cycle;
    EXPECT_NEAR(got.max_rise_pa_per_deg, want.max_rise_pa_per_deg, 2e-3 * want.max_rise_pa_per_deg) << r.cycle;
    EXPECT_NEAR(got.imep_gross_pa, want.imep_gross_pa, 2e-3 * std::abs(want.imep_gross_pa)) << r.cycle;
    EXPECT_NEAR(got.ca50_deg, want.ca50_deg, 0.1) << r.cycle;
  }
  const noisemon::cycle_report_t m = daemon::to_message(reports.back());
  EXPECT_NEAR(m.peak_pressure_bar, 41.5, 0.01);
  EXPECT_NE(daemon::cycle_csv_row(m, "x").find(",41.49"), std::string::npos) << daemon::cycle_csv_row(m, "x");
}

// At 3000 rpm the engine fires 25 times a second: the 20 Hz band (upper edge 22.4 Hz) has no per-cycle meaning.
// It is flagged and left out of the overall levels, so even a strong 20 Hz component does not move them.
TEST(CycleProcessor, BandsBelowTheFiringFrequencyAreFlaggedAndLeftOutOfTheOverallLevels) {
  const RunResult plain = run(Synth({{1000.0, 2000.0, false}}), 1.2);
  const RunResult with_20hz = run(Synth({{1000.0, 2000.0, false}, {20.0, 2e5, false}}), 1.2);
  const std::size_t b20 = band_index(with_20hz.bands, 20), b25 = band_index(with_20hz.bands, 25);
  ASSERT_EQ(plain.reports.size(), with_20hz.reports.size());
  for (std::size_t i = 10; i < plain.reports.size(); ++i) {  // the 25 Hz band settles from the tone's start by then
    const auto& c = with_20hz.reports[i];
    EXPECT_TRUE(c.band_flags[b20] & daemon::kBandBelowFiring);
    EXPECT_FALSE(c.band_flags[b25] & daemon::kBandBelowFiring);
    EXPECT_GT(c.spl_a_predicted_db[b20], plain.reports[i].spl_a_predicted_db[b20] + 20.0);  // it is there, flagged
    EXPECT_NEAR(c.lpa_predicted_db, plain.reports[i].lpa_predicted_db, 0.01);
    EXPECT_NEAR(c.lpa_measured_db, plain.reports[i].lpa_measured_db, 0.01);
  }
}
