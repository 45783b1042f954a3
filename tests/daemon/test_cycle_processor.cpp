// CycleProcessor against analytic references: streams synthesised from tones whose band levels and whose
// response through eq. 4.1 are known in closed form; microphones delayed by the acoustic delay.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include "daemon/cycle_processor.hpp"
#include "daemon/report_messages.hpp"
#include "dsp/math_constants.hpp"

using namespace noisemon;

namespace {

constexpr double kFs = 40000.0;
using noisemon::kPi;
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
  const double ra =
      f4 * f4 * f2s * f2s / ((f2s + f1 * f1) * std::sqrt((f2s + f2 * f2) * (f2s + f3 * f3)) * (f2s + f4 * f4));
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
        10 *
        std::log10(std::pow(10, (level(2000 * std::abs(eq_4_1(1000))) + a_weight(r.bands[b1k].exact_mid_hz)) / 10) +
                   std::pow(10, (level(300 * std::abs(eq_4_1(5000))) + a_weight(r.bands[b5k].exact_mid_hz)) / 10));
    EXPECT_NEAR(c.lpa_measured_db, expected_lpa, 0.2);
    EXPECT_NEAR(c.lpa_predicted_db, expected_lpa, 0.2);
    // The combustion-noise level: the CPL through eq. 4.1's fixed attenuation, A-weighted: the same two tones.
    EXPECT_NEAR(c.combustion_noise_db, expected_lpa, 0.2);
    // Both tones lie within ISO 3744's 100 Hz ... 10 kHz; C1 + C2 at 23 deg C, 101.325 kPa: 5 lg(296.15 / 314) +
    // 15 lg(296.15 / 296), by hand.
    EXPECT_NEAR(c.lwa_measured_db - c.lpa_measured_db, 10 * std::log10(2 * kPi * 1.75 * 1.75) - 0.1271 + 0.0033, 1e-3);
    // Per-microphone levels follow the microphone gains (0.8, 1.0, 1.2 in mean square).
    EXPECT_NEAR(c.mic_lpa_db[2] - c.mic_lpa_db[0], 10 * std::log10(1.2 / 0.8), 0.05);
  }
  EXPECT_EQ(r.counters.cycles_dropped, 0);
}

TEST(CycleProcessor, MicrophoneWindowIsShiftedByTheAcousticDelay) {
  // A 5 kHz tone only in even cycles: with the delay removed, the microphones' level in every cycle follows the
  // pressure's. Without the shift 1/8 of the burst would land in the odd cycles (only ~9 dB down).
  // A weak steady 200 Hz tone keeps every channel moving in the off cycles: a channel exactly constant for a whole
  // cycle is a stuck converter (flat) and would be left out.
  const Synth s({{5000.0, 500.0, true}, {200.0, 1.0, false}});
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
  ASSERT_EQ(fed % kCycleFrames, 128);                       // the premise above
  ASSERT_EQ(reports.size(), wraps - 1);                     // 29: [1600, 3200) ... [46400, 48000)
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
      const std::int64_t shift = mics_stall ? kDelayFrames : 0;     // microphone frame n + d belongs to combined n
      std::int64_t first_after = INT64_MAX;
      const auto start_of = [](const daemon::CycleReport& c) { return (c.utime - 1'000'000) * 40 / 1000; };  // frames
      for (const auto& c : r.reports) {
        const std::int64_t start = start_of(c);  // combined frame where the report's cycle starts
        EXPECT_FALSE(start < gap_to - shift && start + kCycleFrames > gap_from - shift)
            << "cycle " << c.cycle << " overlaps the stall";
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

// One second of a stream with one silent microphone: pressure(encoder angle) at the cell's crank angles.
std::vector<daemon::CycleReport> pressure_run(const daemon::ProcessorConfig& pc,
                                              const std::function<double(double)>& pressure) {
  drivers::StreamInfo info;
  info.epoch_utime = 1'000'000;
  info.mic_count = 1;
  info.radius_m = 1.75;
  info.acoustic_delay_s = 0;
  std::vector<daemon::CycleReport> reports;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { reports.push_back(r); });
  drivers::SampleBlock pb, mb;
  for (std::int64_t b = 0; b * 256 < 40000; ++b) {
    pb.first_index = mb.first_index = b * 256;
    pb.frames = mb.frames = 256;
    pb.channels = drivers::kPressureStreamChannels;
    mb.channels = 1;
    for (int f = 0; f < 256; ++f) {
      const double encoder = crank(b * 256 + f);
      pb.data[f * 2 + drivers::kPressureChannel] = pressure(encoder);
      pb.data[f * 2 + drivers::kCrankChannel] = encoder;
      mb.data[f] = 0.0;
    }
    p.add_pressure(pb);
    p.add_mics(mb);
    p.process();
  }
  return reports;
}

// The combustion metrics of every cycle come from the 40 kHz pressure put back on a crank-angle grid: on a smooth
// combustion pulse (3000 rpm: 0.45 deg per frame) they match the metrics of the pulse sampled on the grid directly.
TEST(CycleProcessor, CombustionMetricsOfEachCycleMatchThoseOfThePressureOnTheCrankAngleGrid) {
  const auto pulse = [](double theta) { return 1.5e5 + 40e5 * std::exp(-std::pow((theta - 8.0) / 15.0, 2)); };
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  const std::vector<daemon::CycleReport> reports = pressure_run(pc, pulse);
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
  EXPECT_EQ(m.tdc_deg, 0.0);
  EXPECT_NE(daemon::cycle_csv_row(m, "x").find(",41.49"), std::string::npos) << daemon::cycle_csv_row(m, "x");
}

// [combustion] tdc_deg: the encoder's angle of firing TDC. An encoder whose zero lies 2.6 deg after firing TDC reads
// the pulse (peak 8 deg after TDC) at 5.4: with tdc_deg = -2.6 the figures are the pulse's own again, the peak at
// 8 deg and the IMEPs those of the pulse on the piston's angles (a grid written out here); with tdc_deg = 0 they
// are not.
TEST(CycleProcessor, TdcDegTurnsTheGridToThePistonsAngles) {
  const double tdc = -2.6;
  const auto pulse = [](double theta) { return 1.5e5 + 40e5 * std::exp(-std::pow((theta - 8.0) / 15.0, 2)); };
  std::vector<double> grid(2881);
  for (std::size_t i = 0; i < grid.size(); ++i) grid[i] = pulse(-360.0 + 0.25 * static_cast<double>(i));
  const model::CombustionMetrics want = model::combustion_metrics(grid, -360.0, 0.25, model::EngineGeometry{}, 3000.0);
  for (const double configured : {tdc, 0.0}) {
    daemon::ProcessorConfig pc;
    pc.model = model::preset("linear");
    pc.metrics.tdc_deg = configured;
    const std::vector<daemon::CycleReport> reports = pressure_run(pc, [&](double encoder) {
      const double piston = encoder - tdc;  // the piston's angle
      return pulse(piston - 720.0 * std::round(piston / 720.0));
    });
    ASSERT_GE(reports.size(), 20u);
    const daemon::CycleReport& r = reports.back();
    EXPECT_EQ(r.tdc_deg, configured);
    if (configured == tdc) {
      EXPECT_NEAR(r.combustion.peak_angle_deg, 8.0, 0.03);
      EXPECT_NEAR(r.combustion.imep_gross_pa, want.imep_gross_pa, 3e-3 * std::abs(want.imep_gross_pa));
      EXPECT_NEAR(r.combustion.imep_net_pa, want.imep_net_pa, 3e-3 * std::abs(want.imep_net_pa));
    } else {
      EXPECT_NEAR(r.combustion.peak_angle_deg, 8.0 + tdc, 0.03);
      EXPECT_GT(std::abs(r.combustion.imep_gross_pa - want.imep_gross_pa), 0.02 * std::abs(want.imep_gross_pa));
    }
  }
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

// ------------------------------------------------------------------------------------------ faulty channels

namespace {

// Streams sample by sample, so that a test can break any channel anywhere: a dead microphone, a NaN burst, a
// clipping converter, an encoder that loses the angle. Frame k of every stream; microphone frame k hears the
// engine at k - kDelayFrames (as Synth does).
struct Streams {
  std::uint32_t mics = kMics;
  std::function<double(std::int64_t)> pressure;
  std::function<double(std::int64_t)> crank = ::crank;
  std::function<double(std::int64_t, std::uint32_t)> mic;
  double pressure_full_scale_pa = 0, mic_full_scale_pa = 0;
  double pressure_edges_per_rev = 0, mic_passband_hz = 0;
};

Streams streams_of(const Synth& s) {
  Streams st;
  st.pressure = [s](std::int64_t k) { return s.pressure(k); };
  st.mic = [s](std::int64_t k, std::uint32_t m) { return s.mic(k, m); };
  return st;
}

// As run(), with an operating point, so that a report's flags say only what the streams did to it.
RunResult run_streams(const Streams& st, double seconds) {
  drivers::StreamInfo info;
  info.epoch_utime = 1'000'000;
  info.mic_count = st.mics;
  info.radius_m = 1.75;
  info.acoustic_delay_s = kDelayFrames / kFs;
  info.pressure_full_scale_pa = st.pressure_full_scale_pa;
  info.mic_full_scale_pa = st.mic_full_scale_pa;
  info.pressure_edges_per_rev = st.pressure_edges_per_rev;
  info.mic_passband_hz = st.mic_passband_hz;
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  RunResult out;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { out.reports.push_back(r); });
  drivers::OperatingPoint op;
  op.speed_rpm = 3000;
  p.set_operating_point(op);
  drivers::SampleBlock pb, mb;
  for (std::int64_t b = 0; b * 256 < static_cast<std::int64_t>(seconds * kFs); ++b) {
    pb.first_index = mb.first_index = b * 256;
    pb.frames = mb.frames = 256;
    pb.channels = drivers::kPressureStreamChannels;
    mb.channels = st.mics;
    for (int f = 0; f < 256; ++f) {
      const std::int64_t k = b * 256 + f;
      pb.data[f * 2 + drivers::kPressureChannel] = st.pressure(k);
      pb.data[f * 2 + drivers::kCrankChannel] = st.crank(k);
      for (std::uint32_t m = 0; m < st.mics; ++m) mb.data[f * st.mics + m] = st.mic(k, m);
    }
    p.add_pressure(pb);
    if (st.mics > 0) p.add_mics(mb);
    p.process();
  }
  out.counters = p.counters();
  out.bands = p.bands();
  return out;
}

// Report cycle n spans combined frames [first_frame(n), first_frame(n) + kCycleFrames): the first boundary is at 1600.
constexpr std::int64_t first_frame(std::int64_t cycle) { return (cycle + 1) * kCycleFrames; }

const daemon::CycleReport* find_cycle(const RunResult& r, std::int64_t cycle) {
  for (const auto& c : r.reports)
    if (c.cycle == cycle) return &c;
  return nullptr;
}

// Every number a report publishes is finite (mic levels of dead microphones aside: -inf for all-zero samples).
void expect_all_finite(const daemon::CycleReport& c) {
  EXPECT_TRUE(std::isfinite(c.lpa_measured_db) && std::isfinite(c.lpa_predicted_db) &&
              std::isfinite(c.lwa_measured_db) && std::isfinite(c.lwa_predicted_db))
      << "cycle " << c.cycle;
  for (std::size_t b = 0; b < c.nbands; ++b)
    EXPECT_TRUE(std::isfinite(c.cpl_db[b]) && std::isfinite(c.spl_a_measured_db[b]) &&
                std::isfinite(c.spl_a_predicted_db[b]) && std::isfinite(c.att_measured_db[b]) &&
                std::isfinite(c.att_predicted_db[b]))
        << "cycle " << c.cycle << " band " << b;
  for (std::size_t m = 0; m < c.nmics; ++m)
    EXPECT_TRUE(std::isfinite(c.mic_lpa_db[m])) << "cycle " << c.cycle << " mic " << m;
}

}  // namespace

// Ten microphones, one of them dead (all zeros: a stuck converter) or unplugged (its converter's noise only,
// 40 dB below the others): it is flagged and left out, and the array level equals that of a second processor that
// is fed the nine good microphones only. Left in, it would pull the energy average down by 10 log10(9/10) = 0.46 dB.
TEST(CycleProcessorFaults, ADeadOrUnpluggedMicrophoneIsLeftOutOfTheArrayAverage) {
  const Synth s({{1000.0, 2000.0, false}, {5000.0, 300.0, false}});
  // Microphone gains spread around 1 (mean square), so that which microphones are averaged matters.
  const auto gain = [](std::uint32_t m) { return std::sqrt(0.7 + 0.06 * m); };
  constexpr std::uint32_t kDead = 3;
  std::mt19937 rng(7);
  std::vector<double> noise(48000);
  for (double& v : noise) v = std::normal_distribution<double>(0.0, 1.0)(rng);
  for (const bool unplugged : {false, true}) {
    SCOPED_TRACE(unplugged ? "unplugged (noise 40 dB down)" : "dead (zeros)");
    Streams ten = streams_of(s);
    ten.mics = 10;
    // Unplugged: white noise with 1 % of a good microphone's rms (the 1 kHz tone through eq. 4.1 dominates it).
    const double noise_rms = 0.01 * 2000 * std::abs(eq_4_1(1000)) / std::sqrt(2.0);
    ten.mic = [&](std::int64_t k, std::uint32_t m) {
      if (m == kDead) return unplugged ? noise_rms * noise[static_cast<std::size_t>(k) % noise.size()] : 0.0;
      return gain(m) * s.mic(k, 1);
    };
    Streams nine = ten;
    nine.mics = 9;
    nine.mic = [&](std::int64_t k, std::uint32_t m) { return gain(m < kDead ? m : m + 1) * s.mic(k, 1); };
    const RunResult r10 = run_streams(ten, 1.2), r9 = run_streams(nine, 1.2);
    ASSERT_EQ(r10.reports.size(), r9.reports.size());
    ASSERT_GE(r10.reports.size(), 25u);
    for (std::size_t i = 0; i < r10.reports.size(); ++i) {
      const auto &a = r10.reports[i], &b = r9.reports[i];
      const std::int8_t want =
          daemon::kMicExcluded | (unplugged ? daemon::kMicLow : daemon::kMicFlat | daemon::kMicLow);
      EXPECT_EQ(a.mic_flags[kDead], want) << "cycle " << a.cycle;
      for (std::uint32_t m = 0; m < 10; ++m)
        if (m != kDead) EXPECT_EQ(a.mic_flags[m], 0) << "cycle " << a.cycle << " mic " << m;
      EXPECT_TRUE(a.flags & daemon::kCycleMicExcluded);
      EXPECT_EQ(a.flags & ~daemon::kCycleSettling, daemon::kCycleMicExcluded) << "cycle " << a.cycle;
      EXPECT_EQ(b.flags & ~daemon::kCycleSettling, 0) << "cycle " << b.cycle;
      EXPECT_NEAR(a.lpa_measured_db, b.lpa_measured_db, 0.01) << "cycle " << a.cycle;
      EXPECT_NEAR(a.lwa_measured_db, b.lwa_measured_db, 0.01) << "cycle " << a.cycle;
      for (std::size_t band = 0; band < a.nbands; ++band) {
        EXPECT_NEAR(a.spl_a_measured_db[band], b.spl_a_measured_db[band], 0.01)
            << "cycle " << a.cycle << " band " << band;
        EXPECT_NEAR(a.att_measured_db[band], b.att_measured_db[band], 0.01) << "cycle " << a.cycle << " band " << band;
      }
      // The dead microphone's own level is still reported: -inf for zeros, about 40 dB down for the noise.
      if (unplugged) {
        EXPECT_NEAR(a.mic_lpa_db[kDead], a.mic_lpa_db[1], 45.0);
        EXPECT_LT(a.mic_lpa_db[kDead], a.mic_lpa_db[1] - 25.0);
      } else {
        EXPECT_EQ(a.mic_lpa_db[kDead], -std::numeric_limits<float>::infinity());
      }
    }
    // The premise: left in, microphone 3 would have moved the average by far more than the tolerance.
    const auto& c = r10.reports.back();
    double all = 0;
    for (std::uint32_t m = 0; m < 10; ++m) all += std::pow(10.0, c.mic_lpa_db[m] / 10.0);
    EXPECT_GT(c.lpa_measured_db - 10 * std::log10(all / 10), 0.4);
  }
}

namespace {

// A replaced stretch ends in a step that the bank's filters ring with: a channel stays faulty while the bands that
// settle within a cycle (the slower ones are flagged BAND_SLOW) have not settled since. The longest of their
// settling times, in frames, for 40 ms cycles: the 400 Hz band's 35 ms.
std::int64_t ring_frames(const std::vector<dsp::ThirdOctaveBand>& bands) {
  double ring = 0;
  for (const auto& b : bands)
    if (b.response_time_s <= kCycleFrames / kFs) ring = std::max(ring, b.response_time_s);
  return static_cast<std::int64_t>(std::ceil(ring * kFs));
}

// A NaN burst early in cycle 10 (it ends more than the ring time before cycle 11), and one that ends 100 frames
// before cycle 11: the cycles that channel is faulty in.
struct Burst {
  const char* name;
  std::int64_t from, to;  // combined frames
  std::vector<std::int64_t> faulty;
};
const std::vector<Burst>& bursts() {
  static const std::vector<Burst> b = {
      {"early in cycle 10", first_frame(10) + 20, first_frame(10) + 160, {10}},
      {"100 frames before cycle 11", first_frame(11) - 500, first_frame(11) - 100, {10, 11}},
  };
  return b;
}

bool in(const std::vector<std::int64_t>& v, std::int64_t x) { return std::find(v.begin(), v.end(), x) != v.end(); }

}  // namespace

// A NaN burst in one microphone: that microphone is left out of the cycles it makes faulty (its NaN never reaches
// the bank, whose filters would stay NaN for ever), and only those; the array level there stays the clean run's
// (microphones 0 and 2 average to the same mean square as all three: with the burst's zeros in, it would drop), and
// every later report is the clean run's again: same flags, no NaN, the same levels.
TEST(CycleProcessorFaults, ANanBurstInAMicrophoneExcludesItUntilItsFiltersHaveSettled) {
  const Synth s({{1000.0, 2000.0, false}, {5000.0, 300.0, false}});
  const RunResult clean = run_streams(streams_of(s), 1.2);
  const std::int64_t ring = ring_frames(clean.bands);
  // About 35 ms: the bursts end on either side of it (1440 and 100 frames before cycle 11).
  ASSERT_GT(ring, 100);
  ASSERT_LT(ring, 1440);
  for (const Burst& burst : bursts()) {
    SCOPED_TRACE(burst.name);
    Streams faulty = streams_of(s);
    faulty.mic = [&](std::int64_t k, std::uint32_t m) {
      const std::int64_t n = k - kDelayFrames;  // the combined frame this microphone sample belongs to
      return m == 1 && n >= burst.from && n < burst.to ? std::numeric_limits<double>::quiet_NaN() : s.mic(k, m);
    };
    const RunResult r = run_streams(faulty, 1.2);
    ASSERT_EQ(r.reports.size(), clean.reports.size());
    EXPECT_EQ(r.counters.samples_replaced, burst.to - burst.from);
    EXPECT_EQ(r.counters.cycles_dropped, 0);
    for (std::size_t i = 0; i < r.reports.size(); ++i) {
      const auto &c = r.reports[i], &ref = clean.reports[i];
      ASSERT_EQ(c.cycle, ref.cycle);
      if (in(burst.faulty, c.cycle)) {
        EXPECT_EQ(c.mic_flags[1], daemon::kMicExcluded | daemon::kMicNan) << "cycle " << c.cycle;
        EXPECT_EQ(c.mic_flags[0] | c.mic_flags[2], 0) << "cycle " << c.cycle;
        EXPECT_EQ(c.flags, ref.flags | daemon::kCycleMicExcluded) << "cycle " << c.cycle;
        EXPECT_NEAR(c.lpa_measured_db, ref.lpa_measured_db, 0.01) << "cycle " << c.cycle;
        EXPECT_TRUE(std::isfinite(c.mic_lpa_db[1])) << "cycle " << c.cycle;  // its own level is still reported
      } else {
        EXPECT_EQ(c.flags, ref.flags) << "cycle " << c.cycle;
        for (std::uint32_t m = 0; m < kMics; ++m) EXPECT_EQ(c.mic_flags[m], 0) << "cycle " << c.cycle;
      }
      if (c.cycle > burst.faulty.back()) {
        expect_all_finite(c);
        EXPECT_NEAR(c.lpa_measured_db, ref.lpa_measured_db, 0.05) << "cycle " << c.cycle;
        EXPECT_NEAR(c.mic_lpa_db[1], ref.mic_lpa_db[1], 0.05) << "cycle " << c.cycle;
      }
    }
    // In the cycle of the burst, microphone 1's own level misses the burst's energy (1/11 or 1/4 of the cycle).
    EXPECT_LT(find_cycle(r, 10)->mic_lpa_db[1], find_cycle(clean, 10)->mic_lpa_db[1] - 0.3);
  }
  // The clean run's premise: its cycles are fully valid (once the filters have settled from the start).
  for (const auto& c : clean.reports) EXPECT_EQ(c.flags & ~daemon::kCycleSettling, 0) << "cycle " << c.cycle;
  EXPECT_EQ(clean.reports.back().flags, 0);
}

// A NaN burst in the pressure: the cycles it makes faulty say so and publish no CPL, prediction, attenuation or
// combustion metric, but their measured levels; the NaN never reaches the block model or the bank, so every later
// cycle predicts what a clean run predicts.
TEST(CycleProcessorFaults, ANanBurstInThePressureVoidsThePredictionsUntilItsFiltersHaveSettled) {
  const Synth s({{1000.0, 2000.0, false}, {5000.0, 300.0, false}});
  const RunResult clean = run_streams(streams_of(s), 1.2);
  const std::size_t b1k = band_index(clean.bands, 1000), b5k = band_index(clean.bands, 5000);
  for (const Burst& burst : bursts()) {
    SCOPED_TRACE(burst.name);
    Streams faulty = streams_of(s);
    faulty.pressure = [&](std::int64_t k) {
      return k >= burst.from && k < burst.to ? std::numeric_limits<double>::quiet_NaN() : s.pressure(k);
    };
    const RunResult r = run_streams(faulty, 1.2);
    ASSERT_EQ(r.reports.size(), clean.reports.size());
    EXPECT_EQ(r.counters.samples_replaced, burst.to - burst.from);
    for (std::size_t i = 0; i < r.reports.size(); ++i) {
      const auto &c = r.reports[i], &ref = clean.reports[i];
      ASSERT_EQ(c.cycle, ref.cycle);
      if (in(burst.faulty, c.cycle)) {
        EXPECT_EQ(c.flags, ref.flags | daemon::kCyclePressureFault) << "cycle " << c.cycle;
        EXPECT_TRUE(std::isnan(c.lpa_predicted_db) && std::isnan(c.lwa_predicted_db)) << "cycle " << c.cycle;
        EXPECT_TRUE(std::isnan(c.combustion.peak_pressure_pa) && std::isnan(c.combustion.imep_gross_pa));
        for (std::size_t b = 0; b < c.nbands; ++b)
          EXPECT_TRUE(std::isnan(c.cpl_db[b]) && std::isnan(c.spl_a_predicted_db[b]) &&
                      std::isnan(c.att_measured_db[b]) && std::isnan(c.att_predicted_db[b]))
              << "cycle " << c.cycle << " band " << b;
        EXPECT_NEAR(c.lpa_measured_db, ref.lpa_measured_db, 1e-9);  // the microphones are untouched
        EXPECT_NEAR(c.spl_a_measured_db[b1k], ref.spl_a_measured_db[b1k], 1e-6);
        for (std::uint32_t m = 0; m < kMics; ++m) EXPECT_EQ(c.mic_flags[m], 0);
        continue;
      }
      EXPECT_EQ(c.flags, ref.flags) << "cycle " << c.cycle;
      if (c.cycle < burst.faulty.front()) continue;
      expect_all_finite(c);
      EXPECT_NEAR(c.lpa_predicted_db, ref.lpa_predicted_db, 0.05) << "cycle " << c.cycle;
      EXPECT_NEAR(c.spl_a_predicted_db[b1k], ref.spl_a_predicted_db[b1k], 0.05) << "cycle " << c.cycle;
      EXPECT_NEAR(c.spl_a_predicted_db[b5k], ref.spl_a_predicted_db[b5k], 0.05) << "cycle " << c.cycle;
      EXPECT_NEAR(c.cpl_db[b1k], ref.cpl_db[b1k], 0.05) << "cycle " << c.cycle;
      EXPECT_NEAR(c.combustion.peak_pressure_pa, ref.combustion.peak_pressure_pa, 1.0) << "cycle " << c.cycle;
    }
  }
}

// Converters that clip: a microphone whose samples reach the rail in one cycle is flagged overloaded and left out
// of that cycle (CYCLE_OVERLOAD, as a sound level meter's overload indicator); one that peaks at 96 % of its full
// scale is not. A pressure that reaches its rail voids the cycle's predictions (CYCLE_PRESSURE_FAULT) and is
// an overload too. Full scale 0 (unknown): nothing is checked.
TEST(CycleProcessorFaults, ClippingAtTheFullScaleIsAnOverload) {
  const Synth s({{1000.0, 2000.0, false}});
  // Peak of the loudest microphone (2, gain sqrt(1.2)): the tone through eq. 4.1. Its rail sits at peak / 0.96: 4 %
  // of headroom, below the 0.99 threshold.
  const double peak2 = 2000 * std::abs(eq_4_1(1000)) * Synth::gain(2);
  const double mic_fs = peak2 / 0.96;
  const double pressure_fs = (1e5 + 2000) / 0.96;  // the pressure's peak at 96 % of its (absolute) rail too
  constexpr std::int64_t kMicCycle = 10, kPressureCycle = 14;
  const auto in_cycle = [](std::int64_t n, std::int64_t cycle) {
    return n >= first_frame(cycle) && n < first_frame(cycle + 1);
  };
  Streams st = streams_of(s);
  st.mic_full_scale_pa = mic_fs;
  st.pressure_full_scale_pa = pressure_fs;
  // Microphone 2 hears 1.6 dB more in cycle kMicCycle: beyond its rail, clipped there. Clipped samples after the
  // resampling to 40 kHz stay a little below the rail itself: 99.5 % of it here.
  constexpr double kClipped = 0.995;
  st.mic = [&](std::int64_t k, std::uint32_t m) {
    const double x = s.mic(k, m);
    return m == 2 && in_cycle(k - kDelayFrames, kMicCycle) ? std::clamp(1.2 * x, -kClipped * mic_fs, kClipped * mic_fs)
                                                           : x;
  };
  // The pressure swings four times as far in cycle kPressureCycle: beyond its rail, clipped there.
  st.pressure = [&](std::int64_t k) {
    const double p = s.pressure(k);
    return in_cycle(k, kPressureCycle) ? std::min(1e5 + 4 * (p - 1e5), kClipped * pressure_fs) : p;
  };
  const RunResult r = run_streams(st, 1.0);
  ASSERT_NE(find_cycle(r, kPressureCycle + 1), nullptr);
  for (const auto& c : r.reports) {
    if (c.cycle == kMicCycle) {
      EXPECT_EQ(c.mic_flags[2], daemon::kMicExcluded | daemon::kMicOverload);
      EXPECT_EQ(c.flags & ~daemon::kCycleSettling, daemon::kCycleOverload | daemon::kCycleMicExcluded);
    } else if (c.cycle == kPressureCycle) {
      EXPECT_EQ(c.flags & ~daemon::kCycleSettling, daemon::kCycleOverload | daemon::kCyclePressureFault);
      EXPECT_TRUE(std::isnan(c.lpa_predicted_db));
      EXPECT_TRUE(std::isfinite(c.lpa_measured_db));
    } else {
      EXPECT_EQ(c.flags & ~daemon::kCycleSettling, 0) << "cycle " << c.cycle;  // microphone 2 at 96 %: no overload
    }
    if (c.cycle != kMicCycle)
      for (std::uint32_t m = 0; m < kMics; ++m) EXPECT_EQ(c.mic_flags[m], 0) << "cycle " << c.cycle << " mic " << m;
  }
  // The same streams with the full scales unknown: no overload anywhere.
  st.mic_full_scale_pa = st.pressure_full_scale_pa = 0;
  for (const auto& c : run_streams(st, 1.0).reports)
    EXPECT_EQ(c.flags & ~daemon::kCycleSettling, 0) << "cycle " << c.cycle;
}

namespace {

// A combustion pulse (as in the metrics test above) with a 1 kHz ripple, so that every cycle has combustion metrics.
Streams combustion_streams() {
  const Synth s({{1000.0, 2000.0, false}});
  Streams st = streams_of(s);
  st.pressure = [s](std::int64_t k) { return s.pressure(k) + 40e5 * std::exp(-std::pow((crank(k) - 8.0) / 15.0, 2)); };
  return st;
}

Streams with_crank_unknown(Streams st, std::int64_t from, std::int64_t to) {
  st.crank = [from, to](std::int64_t k) {
    return k >= from && k < to ? std::numeric_limits<double>::quiet_NaN() : crank(k);
  };
  return st;
}

}  // namespace

// The encoder loses the angle for 300 frames (135 deg) in the middle of one cycle: that cycle is flagged and has no
// combustion metrics (its pressure has a hole on the crank-angle grid); its neighbours are untouched, no cycle is
// lost or invented, and the levels (time-based) are those of a clean run.
TEST(CycleProcessorFaults, UnknownCrankAngleInsideACycleFlagsThatCycleOnly) {
  constexpr std::int64_t kCycle = 10, kFrom = first_frame(kCycle) + 400, kTo = kFrom + 300;
  const RunResult clean = run_streams(combustion_streams(), 1.0);
  const RunResult r = run_streams(with_crank_unknown(combustion_streams(), kFrom, kTo), 1.0);
  ASSERT_EQ(r.reports.size(), clean.reports.size());
  EXPECT_EQ(r.counters.cycles_dropped, 0);
  EXPECT_EQ(r.counters.crank_unknown_frames, kTo - kFrom);
  for (std::size_t i = 0; i < r.reports.size(); ++i) {
    const auto &c = r.reports[i], &ref = clean.reports[i];
    ASSERT_EQ(c.cycle, ref.cycle);
    ASSERT_EQ(c.utime, ref.utime);
    EXPECT_TRUE(std::isfinite(ref.combustion.peak_pressure_pa) && std::isfinite(ref.combustion.imep_gross_pa));
    if (c.cycle == kCycle) {
      EXPECT_EQ(c.flags & ~ref.flags, daemon::kCycleEncoder);
      EXPECT_TRUE(std::isnan(c.combustion.peak_pressure_pa));
      EXPECT_TRUE(std::isnan(c.combustion.imep_gross_pa));
      EXPECT_TRUE(std::isnan(c.combustion.ca50_deg));
    } else {
      EXPECT_EQ(c.flags, ref.flags) << "cycle " << c.cycle;
      EXPECT_EQ(c.combustion.peak_pressure_pa, ref.combustion.peak_pressure_pa) << "cycle " << c.cycle;
      EXPECT_EQ(c.combustion.imep_gross_pa, ref.combustion.imep_gross_pa) << "cycle " << c.cycle;
    }
    EXPECT_NEAR(c.lpa_measured_db, ref.lpa_measured_db, 1e-9) << "cycle " << c.cycle;
    EXPECT_NEAR(c.lpa_predicted_db, ref.lpa_predicted_db, 1e-9) << "cycle " << c.cycle;
  }
}

// The encoder loses the angle across a cycle boundary. Longer than a cycle (the angle after it is past the one
// before it: no wrap seen), the boundaries inside are hidden: the 2-cycle stretch between the boundaries around it
// is not reported and counts as two dropped cycles, and the next cycle (starting at a boundary seen on known angles)
// is valid again, with the clean run's index. Shorter (a wrap is seen at the first known angle), the boundary is
// uncertain: the cycles before and after it are flagged, not dropped, and do not become the reference length.
TEST(CycleProcessorFaults, UnknownCrankAngleAcrossABoundaryHidesOrBlursIt) {
  const RunResult clean = run_streams(combustion_streams(), 1.0);
  struct Case {
    const char* name;
    std::int64_t from, to;              // unknown crank angles, combined frames
    std::vector<std::int64_t> gone;     // report indices not published
    std::vector<std::int64_t> blurred;  // published with CYCLE_ENCODER
  };
  const std::vector<Case> cases = {
      {"1.13 cycles, covering the boundary at the start of cycle 11",
       first_frame(10) + 1000,
       first_frame(11) + 1200,
       {10, 11},
       {}},
      {"400 frames around the boundary at the start of cycle 11",
       first_frame(11) - 200,
       first_frame(11) + 200,
       {},
       {10, 11}},
  };
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    const RunResult r = run_streams(with_crank_unknown(combustion_streams(), k.from, k.to), 1.0);
    EXPECT_EQ(r.counters.cycles_dropped, static_cast<std::int64_t>(k.gone.size()));
    EXPECT_EQ(r.reports.size() + k.gone.size(), clean.reports.size());
    std::int64_t first_valid_after = INT64_MAX;
    for (const auto& c : r.reports) {
      EXPECT_EQ(std::count(k.gone.begin(), k.gone.end(), c.cycle), 0) << "cycle " << c.cycle << " published";
      const daemon::CycleReport* ref = find_cycle(clean, c.cycle);
      ASSERT_NE(ref, nullptr) << "cycle " << c.cycle;
      const bool blurred = std::count(k.blurred.begin(), k.blurred.end(), c.cycle) > 0;
      EXPECT_EQ((c.flags & daemon::kCycleEncoder) != 0, blurred) << "cycle " << c.cycle;
      if (blurred) {
        EXPECT_TRUE(std::isnan(c.combustion.peak_pressure_pa)) << "cycle " << c.cycle;
        continue;
      }
      // Every other cycle is the clean run's: same start, same flags (no odd length after the blurred ones),
      // same metrics.
      EXPECT_EQ(c.utime, ref->utime) << "cycle " << c.cycle;
      EXPECT_EQ(c.flags, ref->flags) << "cycle " << c.cycle;
      EXPECT_NEAR(c.combustion.peak_pressure_pa, ref->combustion.peak_pressure_pa, 1e-6) << "cycle " << c.cycle;
      const std::int64_t start = (c.utime - 1'000'000) * 40 / 1000;
      if (start >= k.to && (c.flags & ~daemon::kCycleSettling) == 0)
        first_valid_after = std::min(first_valid_after, start);
    }
    EXPECT_LE(first_valid_after, k.to + 2 * kCycleFrames) << "no valid cycle within two cycles of the stretch's end";
    // The blurred boundary sits at the first known angle: the cycle before it is longer, the one after shorter.
    if (!k.blurred.empty()) {
      const daemon::CycleReport *before = find_cycle(r, k.blurred[0]), *after = find_cycle(r, k.blurred[1]);
      ASSERT_TRUE(before && after);
      EXPECT_NEAR(before->duration_s, (first_frame(11) + 200 - first_frame(10)) / kFs, 1e-9);
      EXPECT_NEAR(after->duration_s, (first_frame(12) - first_frame(11) - 200) / kFs, 1e-9);
    }
  }
}

// What the streams cannot carry is flagged and left out of the overall levels. A pressure sampled at every degree
// (360 edges per revolution) at 3000 rpm has an 18 kHz edge rate: the crank-angle resampler is flat to 0.41 of it
// (7.4 kHz; tests/dsp/test_resample.cpp measures that flatness), so the 8 kHz band (upper edge 8.9 kHz) and above
// are flagged; microphones behind a 10 kHz passband flag the 10 kHz band (upper edge 11.2 kHz) and above. A strong
// 12.5 kHz tone then does not move the overall levels: they are the 5 kHz tone's alone, as eq. 4.1 gives it.
TEST(CycleProcessor, BandsTheStreamsCannotCarryAreFlaggedAndLeftOutOfTheOverallLevels) {
  const Synth s({{5000.0, 300.0, false}, {12500.0, 30000.0, false}});
  Streams st = streams_of(s);
  st.pressure_edges_per_rev = 360;
  st.mic_passband_hz = 10000;
  const RunResult r = run_streams(st, 1.2);
  ASSERT_GE(r.reports.size(), 20u);
  const std::size_t b6k3 = band_index(r.bands, 6300), b8k = band_index(r.bands, 8000),
                    b10k = band_index(r.bands, 10000);
  const double expected_lpa =
      level(300 * std::abs(eq_4_1(5000))) + a_weight(r.bands[band_index(r.bands, 5000)].exact_mid_hz);
  for (const auto& c : r.reports) {
    EXPECT_FALSE(c.band_flags[b6k3] & (daemon::kBandPressurePassband | daemon::kBandMicPassband));
    EXPECT_TRUE(c.band_flags[b8k] & daemon::kBandPressurePassband);
    EXPECT_FALSE(c.band_flags[b8k] & daemon::kBandMicPassband);
    for (std::size_t b = b10k; b < r.bands.size(); ++b) {
      EXPECT_TRUE(c.band_flags[b] & daemon::kBandPressurePassband) << r.bands[b].nominal_hz;
      EXPECT_TRUE(c.band_flags[b] & daemon::kBandMicPassband) << r.bands[b].nominal_hz;
    }
    if (c.cycle < 5) continue;                                                        // let the filters settle
    EXPECT_GT(c.spl_a_measured_db[band_index(r.bands, 12500)], expected_lpa + 10.0);  // it is there, flagged
    EXPECT_NEAR(c.lpa_measured_db, expected_lpa, 0.2);
    EXPECT_NEAR(c.lpa_predicted_db, expected_lpa, 0.2);
  }
  // Without the limits (a source that does not say), nothing is flagged and the 12.5 kHz tone dominates.
  const RunResult unlimited = run_streams(streams_of(s), 1.2);
  for (const auto& c : unlimited.reports) {
    for (std::size_t b = 0; b < r.bands.size(); ++b)
      EXPECT_FALSE(c.band_flags[b] & (daemon::kBandPressurePassband | daemon::kBandMicPassband));
    if (c.cycle >= 5) EXPECT_GT(c.lpa_measured_db, expected_lpa + 10.0);
  }
}
