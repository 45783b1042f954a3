// Recording <-> run directory <-> raw LCM log.
//
// Round trip on analytic signals: an encoder at 0.2 deg on a crank with 1 % speed ripple sampling a pressure
// curve known in closed form, and a two-channel 51.2 kHz WAV of sines. Every 40 kHz frame, after run dir ->
// recording -> log -> recording -> run dir, is compared with the analytic value at its instant; the limits are
// the resamplers' documented errors (relative rms 6e-6 .. 3e-5, see tests/dsp/test_resample.cpp) with margin.
// Measured (RelWithDebInfo): pressure relative rms error 1.4e-6 (max 1.5e-6 of the peak); crank 4e-7 deg
// (linear interpolation between 0.2 deg edges); microphones relative rms 1e-5. Every 500th encoder sample
// missing (filled by interpolation): max pressure error 2.7e-5 of the peak.
//
// Damaged logs: each damage is made by hand at a byte offset found by walking the LCM log format in the test;
// what comes back is checked frame by frame against the original (nothing invented, nothing shifted).
#include <gtest/gtest.h>
#include <sndfile.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <numbers>

#include "cli/formats/angle_edges.hpp"
#include "cli/formats/recording.hpp"
#include "drivers/formats/lcm_log_reader.hpp"
#include "drivers/formats/stream_messages.hpp"
#include "dsp/math_constants.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

using namespace noisemon::drivers;
using namespace noisemon::cli::formats;
namespace fs = std::filesystem;

namespace {

using noisemon::kPi;
constexpr double kOmega = 6.0 * 2000.0;               // deg/s at 2000 rpm
constexpr double kCycleS = 720.0 / kOmega;            // 0.06 s
constexpr double kRipple = 0.01 * 720.0 / (2 * kPi);  // deg: 1 % speed ripple once per cycle
constexpr double kTheta0 = -300.0;

double theta_at(double t) { return kTheta0 + kOmega * t + kRipple * std::sin(2 * kPi * t / kCycleS); }
double time_at(double theta) {  // Newton on the monotone theta(t)
  double t = (theta - kTheta0) / kOmega;
  for (int i = 0; i < 50; ++i) {
    const double f = theta_at(t) - theta;
    const double d = kOmega + kRipple * 2 * kPi / kCycleS * std::cos(2 * kPi * t / kCycleS);
    t -= f / d;
    if (std::abs(f) < 1e-13) break;
  }
  return t;
}
// A combustion-like peak at every firing TDC (a Gaussian in crank angle) on 1 bar, plus a 3 kHz component.
double pressure_at(double t) {
  const double th = theta_at(t);
  const double c = th - 720.0 * std::round(th / 720.0);
  return 1e5 + 5e6 * std::exp(-0.5 * (c / 20.0) * (c / 20.0)) + 2e3 * std::sin(2 * kPi * 3000.0 * t);
}
double mic_at(int ch, double t) {
  return ch == 0 ? 0.5 * std::sin(2 * kPi * 1000.0 * t) : 0.2 * std::sin(2 * kPi * 7000.0 * t + 0.3);
}
double wrap(double th) { return th - 720.0 * std::floor((th + 360.0) / 720.0); }

formats::RunDir analytic_run(double seconds) {
  formats::RunDir run;
  run.condition = {"analytic", 2000.0, 12.5, 15.0, 800.0, false};
  for (int m = 0;; ++m) {
    const double th = kTheta0 + 0.2 * m;
    const double t = time_at(th);
    if (t > seconds) break;
    run.time_s.push_back(t);
    run.crank_deg.push_back(th);
    run.pressure_pa.push_back(pressure_at(t));
  }
  run.mic_count = 2;
  run.mic_rate_hz = 51200;
  for (int k = 0; k < static_cast<int>(seconds * 51200); ++k)
    for (int c = 0; c < 2; ++c) run.mic_pa.push_back(static_cast<float>(mic_at(c, k / 51200.0)));
  run.mic_positions_m = {{-1.35, 0.78, 0.79}, {0.2, -0.3, 1.7}};
  run.radius_m = 1.75;
  run.acoustic_delay_s = 0.0051;
  return run;
}

struct Errors {
  double pressure_rel_rms, pressure_max_rel, crank_max_deg, mic_rel_rms;
};

// Compares 40 kHz frames (pressure, wrapped crank, mics) with the analytic signals at t = (first + i) / 40 kHz.
Errors compare(std::int64_t first, const std::vector<double>& p, const std::vector<double>& crank_wrapped,
               const std::vector<double>& mics) {
  double pe = 0, pr = 0, pmax = 0, cmax = 0, me = 0, mr = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double t = static_cast<double>(first + static_cast<std::int64_t>(i)) / 40000.0;
    const double ref = pressure_at(t) - 1e5;  // the error relative to the varying part, not the mean
    pe += std::pow(p[i] - 1e5 - ref, 2);
    pr += ref * ref;
    pmax = std::max(pmax, std::abs(p[i] - 1e5 - ref) / 5e6);
    cmax = std::max(cmax, std::abs(crank_wrapped[i] - wrap(theta_at(t))));
    for (int c = 0; c < 2; ++c) {
      me += std::pow(mics[2 * i + c] - mic_at(c, t), 2);
      mr += std::pow(mic_at(c, t), 2);
    }
  }
  return {std::sqrt(pe / pr), pmax, cmax, std::sqrt(me / mr)};
}

fs::path recording_temp(const std::string& name) {
  return fs::path(noisemon::test::unique_temp_dir()) / ("recording_" + name);
}

std::vector<std::uint8_t> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const fs::path& p, const std::vector<std::uint8_t>& b) {
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// Event layout of an LCM log, walked from the format (sync, eventnum, timestamp, channel length, data length).
struct EventAt {
  std::size_t offset, data_offset;
  std::string channel;
  std::uint32_t datalen;
};
std::vector<EventAt> walk(const std::vector<std::uint8_t>& b) {
  std::vector<EventAt> out;
  std::size_t pos = 0;
  const auto u32 = [&](std::size_t at) {
    return (std::uint32_t{b[at]} << 24) | (b[at + 1] << 16) | (b[at + 2] << 8) | b[at + 3];
  };
  while (pos + 28 <= b.size()) {
    const std::uint32_t ch = u32(pos + 20), dl = u32(pos + 24);
    out.push_back({pos, pos + 28 + ch, std::string(reinterpret_cast<const char*>(&b[pos + 28]), ch), dl});
    pos += 28 + ch + dl;
  }
  return out;
}

// A small recording: 0.25 s, one microphone at 40 kHz, crank at 3000 rpm.
Recording small_recording(const std::string& condition, std::int64_t epoch) {
  Recording r;
  r.condition = condition;
  r.info.epoch_utime = epoch;
  r.info.mic_count = 1;
  r.info.mic_positions_m = {{0, 0, 1.75}};
  r.info.acoustic_delay_s = 0.005;
  r.first_index = 1000;
  for (int i = 0; i < 10000; ++i) {
    r.pressure_pa.push_back(1e5 + 1e3 * std::sin(0.01 * i));
    r.crank_deg.push_back(wrap(-100.0 + 0.45 * i));
    r.mics_pa.push_back(0.1 * std::cos(0.02 * i));
  }
  OperatingPoint op;
  op.utime = epoch + 25000;
  op.speed_rpm = 3000;
  op.load_nm = 3;
  op.soi_deg_btdc = 18;
  op.rail_pressure_bar = std::nan("");
  r.operating_points = {op};
  return r;
}

// Every frame of every piece equals the original's frame at the same grid index.
void expect_subset_of(const std::vector<Recording>& pieces, const Recording& original, std::size_t* frames = nullptr) {
  std::size_t total = 0;
  for (const Recording& p : pieces) {
    ASSERT_EQ(p.info.epoch_utime, original.info.epoch_utime);
    ASSERT_GE(p.first_index, original.first_index);
    ASSERT_LE(p.first_index + static_cast<std::int64_t>(p.frames()),
              original.first_index + static_cast<std::int64_t>(original.frames()));
    const auto off = static_cast<std::size_t>(p.first_index - original.first_index);
    for (std::size_t i = 0; i < p.frames(); ++i) {
      ASSERT_EQ(p.pressure_pa[i], original.pressure_pa[off + i]) << "frame " << i;
      ASSERT_EQ(p.crank_deg[i], original.crank_deg[off + i]);
      ASSERT_EQ(p.mics_pa[i], original.mics_pa[off + i]);
    }
    total += p.frames();
  }
  if (frames) *frames = total;
}

fs::path good_log(const std::string& name, const Recording& rec) {
  const fs::path p = recording_temp(name + ".lcmlog");
  write_recordings_log(p, {rec});
  return p;
}

}  // namespace

TEST(Recording, RunDirToLogAndBackMatchesTheAnalyticSignals) {
  const formats::RunDir run = analytic_run(0.5);
  const Recording rec = to_recording(run, 1'000'000'000'000);
  ASSERT_GT(rec.frames(), 19000u);  // 0.5 s less the resamplers' edges
  Errors e = compare(rec.first_index, rec.pressure_pa, rec.crank_deg, rec.mics_pa);
  std::printf("to_recording: pressure rel rms %.2g (max %.2g of the peak), crank max %.2g deg, mics rel rms %.2g\n",
              e.pressure_rel_rms, e.pressure_max_rel, e.crank_max_deg, e.mic_rel_rms);
  EXPECT_LT(e.pressure_rel_rms, 1e-4);
  EXPECT_LT(e.pressure_max_rel, 1e-4);
  EXPECT_LT(e.crank_max_deg, 1e-4);
  EXPECT_LT(e.mic_rel_rms, 1e-4);
  EXPECT_EQ(rec.condition, "analytic");
  EXPECT_EQ(rec.info.mic_count, 2u);
  EXPECT_EQ(rec.info.acoustic_delay_s, 0.0051);

  // Through an LCM log: bit-exact.
  const fs::path log = recording_temp("analytic.lcmlog");
  write_recordings_log(log, {rec});
  std::int64_t skipped = -1;
  const std::vector<Recording> back = read_recordings_log(log, {}, &skipped);
  EXPECT_EQ(skipped, 0);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].first_index, rec.first_index);
  EXPECT_EQ(back[0].pressure_pa, rec.pressure_pa);
  EXPECT_EQ(back[0].crank_deg, rec.crank_deg);
  EXPECT_EQ(back[0].mics_pa, rec.mics_pa);
  // The encoder samples within the frames, as the run has them, are the crank-angle stream: read back, each edge's
  // angle and pressure exactly, its instant its block's first frame (at most a block's 90 deg before it).
  const double step = 360.0 / rec.info.pressure_edges_per_rev;
  EXPECT_NEAR(rec.info.pressure_angle_step_deg, step, 1e-12);
  const std::size_t edges = rec.angle_edges.size() / kEdgeValues;
  std::size_t within = 0;
  for (std::size_t i = 0; i < run.time_s.size(); ++i) {
    const double t = run.time_s[i] * 40000.0;
    if (t < static_cast<double>(rec.first_index) ||
        t >= static_cast<double>(rec.first_index + static_cast<std::int64_t>(rec.frames())))
      continue;
    ASSERT_LT(within, edges);
    EXPECT_EQ(rec.angle_edges[within * kEdgeValues + kEdgeInstant], t);
    EXPECT_EQ(rec.angle_edges[within * kEdgeValues + kEdgePressure], run.pressure_pa[i]);
    EXPECT_NEAR(rec.angle_edges[within * kEdgeValues + kEdgeCrank], wrap(run.crank_deg[i]), 1e-9);
    ++within;
  }
  EXPECT_EQ(within, edges);
  EXPECT_GT(edges, 1000u);
  ASSERT_EQ(back[0].angle_edges.size(), rec.angle_edges.size());
  const double block_frames = 1.05 * 90.0 / 360.0 * 60.0 / 2000.0 * 40000.0;  // 90 deg at 2000 rpm (1 % ripple)
  for (std::size_t i = 0; i < edges; ++i) {
    EXPECT_EQ(back[0].angle_edges[i * kEdgeValues + kEdgeCrank], rec.angle_edges[i * kEdgeValues + kEdgeCrank]);
    EXPECT_EQ(back[0].angle_edges[i * kEdgeValues + kEdgePressure], rec.angle_edges[i * kEdgeValues + kEdgePressure]);
    const double lag =
        rec.angle_edges[i * kEdgeValues + kEdgeInstant] - back[0].angle_edges[i * kEdgeValues + kEdgeInstant];
    ASSERT_GE(lag, 0.0) << i;
    ASSERT_LE(lag, block_frames + 1.0) << i;
  }
  EXPECT_EQ(back[0].condition, "analytic");
  EXPECT_EQ(back[0].info.epoch_utime, rec.info.epoch_utime);
  EXPECT_EQ(back[0].info.mic_positions_m, run.mic_positions_m);
  EXPECT_EQ(back[0].info.radius_m, 1.75);
  EXPECT_EQ(back[0].info.acoustic_delay_s, 0.0051);
  ASSERT_EQ(back[0].operating_points.size(), 1u);
  const OperatingPoint& op = back[0].operating_points[0];
  EXPECT_EQ(op.speed_rpm, 2000.0);
  EXPECT_EQ(op.load_nm, 12.5);
  EXPECT_EQ(op.soi_deg_btdc, 15.0);
  EXPECT_EQ(op.rail_pressure_bar, 800.0);
  EXPECT_FALSE(op.motored);

  // And out to a run directory again: time_s = 0 at the first frame, crank unwrapped, mics at 40 kHz.
  const fs::path dir = recording_temp("analytic_dir");
  fs::remove_all(dir);
  write_run_dir(dir, to_run_dir(back[0]));
  const formats::RunDir out = formats::read_run_dir(dir);
  EXPECT_EQ(out.condition.name, "analytic");
  EXPECT_EQ(out.condition.speed_rpm, 2000.0);
  EXPECT_EQ(out.condition.load_nm, 12.5);
  EXPECT_EQ(out.condition.soi_deg_btdc, 15.0);
  EXPECT_EQ(out.condition.rail_pressure_bar.value_or(-1), 800.0);
  EXPECT_EQ(out.mic_positions_m, run.mic_positions_m);
  EXPECT_EQ(out.mic_rate_hz, 40000.0);
  EXPECT_EQ(out.acoustic_delay_s, 0.0051);
  ASSERT_EQ(out.time_s.size(), rec.frames());
  std::vector<double> wrapped(out.crank_deg.size()), mics(out.mic_pa.begin(), out.mic_pa.end());
  double unwrap_err = 0;
  for (std::size_t i = 0; i < out.crank_deg.size(); ++i) {
    ASSERT_EQ(out.time_s[i], static_cast<double>(i) / 40000.0);
    wrapped[i] = wrap(out.crank_deg[i]);
    // The first frame lies in cycle 0, so the unwrapped angle is the analytic one.
    unwrap_err = std::max(unwrap_err,
                          std::abs(out.crank_deg[i] - theta_at((rec.first_index + static_cast<double>(i)) / 40000.0)));
  }
  EXPECT_LT(unwrap_err, 1e-4);
  e = compare(rec.first_index, out.pressure_pa, wrapped, mics);
  EXPECT_LT(e.pressure_rel_rms, 1e-4);
  EXPECT_LT(e.mic_rel_rms, 1e-4);

  // That run directory imports without resampling again (already on the grid): the same frames.
  const Recording again = to_recording(out, rec.info.epoch_utime);
  ASSERT_EQ(again.frames(), rec.frames());
  for (std::size_t i = 0; i < rec.frames(); ++i) {
    ASSERT_NEAR(again.pressure_pa[i], rec.pressure_pa[i], 1e-9 * rec.pressure_pa[i]);
    ASSERT_NEAR(again.crank_deg[i], rec.crank_deg[i], 1e-9);
    ASSERT_NEAR(again.mics_pa[2 * i], rec.mics_pa[2 * i], 1e-7);  // 32-bit float WAV
  }
}

TEST(Recording, MissingEncoderSamplesAreFilledNotWarped) {
  formats::RunDir run = analytic_run(0.2);
  run.mic_count = 0;
  run.mic_pa.clear();
  run.mic_positions_m.clear();
  // Drop every 500th encoder sample (a missing edge every 100 deg).
  formats::RunDir holes = run;
  holes.time_s.clear();
  holes.crank_deg.clear();
  holes.pressure_pa.clear();
  for (std::size_t i = 0; i < run.time_s.size(); ++i) {
    if (i % 500 == 250) continue;
    holes.time_s.push_back(run.time_s[i]);
    holes.crank_deg.push_back(run.crank_deg[i]);
    holes.pressure_pa.push_back(run.pressure_pa[i]);
  }
  const Recording rec = to_recording(holes, 0);
  double err = 0;
  for (std::size_t i = 0; i < rec.frames(); ++i)
    err = std::max(
        err, std::abs(rec.pressure_pa[i] -
                      pressure_at(static_cast<double>(rec.first_index + static_cast<std::int64_t>(i)) / 40000.0)));
  std::printf("missing encoder samples: max error %.3g Pa of a 5e6 Pa peak\n", err);
  EXPECT_LT(err, 1e-3 * 5e6);
}

TEST(Recording, PressureAndMicsThatDoNotOverlapAreAnError) {
  formats::RunDir run = analytic_run(0.1);
  for (double& t : run.time_s) t += 5.0;  // pressure 5 s after the WAV ends
  try {
    to_recording(run, 0);
    ADD_FAILURE() << "no error";
  } catch (const formats::RunDirError& e) {
    EXPECT_NE(std::string(e.what()).find("do not overlap in time"), std::string::npos) << e.what();
  }
}

TEST(RecordingUnknowns, ANullSpeedIsMeasuredFromTheEncoder) {
  formats::RunDir run = analytic_run(0.5);  // 2000 rpm with a 1 % ripple once per cycle
  run.condition.speed_rpm = std::nan("");
  const Recording rec = to_recording(run, 0);
  ASSERT_EQ(rec.operating_points.size(), 1u);
  const double rpm = rec.operating_points[0].speed_rpm;
  std::printf("speed from the encoder: %.4f rpm (true mean 2000)\n", rpm);
  EXPECT_NEAR(rpm, 2000.0, 0.005 * 2000.0);
  EXPECT_NEAR(formats::encoder_speed_rpm(run), rpm, 1e-9);
}

namespace {

// 2.5 s at 40 kHz (the writer repeats the operating point every second) with the given point.
Recording long_recording(const OperatingPoint& op) {
  Recording r = small_recording("unknowns", 5'000'000);
  r.pressure_pa.clear();
  r.crank_deg.clear();
  r.mics_pa.clear();
  for (int i = 0; i < 100000; ++i) {
    r.pressure_pa.push_back(1e5 + 1e3 * std::sin(0.01 * i));
    r.crank_deg.push_back(wrap(-100.0 + 0.45 * i));
    r.mics_pa.push_back(0.1 * std::cos(0.02 * i));
  }
  r.operating_points = {op};
  return r;
}

}  // namespace

TEST(RecordingUnknowns, UnknownValuesTravelAsNaNThroughTheLogAndAreWrittenAsNull) {
  formats::RunDir run = analytic_run(0.2);
  run.condition = {"nulls", 2000.0, std::nan(""), std::nan(""), std::nullopt, false, false};
  const Recording rec = to_recording(run, 5'000'000);
  ASSERT_EQ(rec.operating_points.size(), 1u);
  OperatingPoint op = rec.operating_points[0];
  EXPECT_TRUE(std::isnan(op.load_nm));
  EXPECT_TRUE(std::isnan(op.soi_deg_btdc));
  EXPECT_TRUE(std::isnan(op.rail_pressure_bar));
  EXPECT_FALSE(op.motored);  // unknown: the boolean message says false
  // Through a log where the point is repeated every second: NaN is not "a new value" at each repeat.
  op.speed_rpm = 3000.0;                                        // the long recording's crank speed
  op.soi_deg_btdc = -std::numeric_limits<double>::quiet_NaN();  // sign bit set, as 0.0 / 0.0 gives on x86
  const fs::path log = recording_temp("unknowns.lcmlog");
  write_recordings_log(log, {long_recording(op)});
  const std::vector<Recording> back = read_recordings_log(log);
  ASSERT_EQ(back.size(), 1u);
  ASSERT_EQ(back[0].operating_points.size(), 1u);
  const OperatingPoint& b = back[0].operating_points[0];
  EXPECT_EQ(b.speed_rpm, 3000.0);
  EXPECT_TRUE(std::isnan(b.load_nm));
  EXPECT_TRUE(std::isnan(b.soi_deg_btdc));
  EXPECT_FALSE(std::signbit(b.soi_deg_btdc));  // one NaN for every unknown: printed "nan", never "-nan"
  EXPECT_TRUE(std::isnan(b.rail_pressure_bar));
  // Out as a run directory: null, not 0, and unknown again when read.
  const fs::path dir = recording_temp("unknowns_dir");
  fs::remove_all(dir);
  write_run_dir(dir, to_run_dir(back[0]));
  const std::string text = noisemon::test::slurp(dir / "run.json");
  for (const char* key : {"load_nm", "soi_deg_btdc", "rail_pressure_bar"})
    EXPECT_NE(text.find("\"" + std::string(key) + "\": null"), std::string::npos) << key << " in " << text;
  const formats::RunDir again = formats::read_run_dir(dir);
  EXPECT_TRUE(std::isnan(again.condition.load_nm));
  EXPECT_TRUE(std::isnan(again.condition.soi_deg_btdc));
  EXPECT_EQ(again.condition.speed_rpm, 3000.0);
}

TEST(RecordingUnknowns, ALogWithoutOperatingPointsHasAMeasuredSpeedAndNothingMadeUp) {
  Recording rec = long_recording({});
  rec.operating_points.clear();
  const fs::path log = recording_temp("no_op.lcmlog");
  write_recordings_log(log, {rec});
  const std::vector<Recording> back = read_recordings_log(log);
  ASSERT_EQ(back.size(), 1u);
  ASSERT_EQ(back[0].operating_points.size(), 1u);
  const OperatingPoint& op = back[0].operating_points[0];
  EXPECT_NEAR(op.speed_rpm, 0.45 * 40000.0 / 6.0, 1e-6);  // 0.45 deg per 40 kHz frame
  EXPECT_TRUE(std::isnan(op.load_nm));
  EXPECT_TRUE(std::isnan(op.soi_deg_btdc));
  EXPECT_TRUE(std::isnan(op.rail_pressure_bar));
}

TEST(LcmLogReader, ReadsWhatLcmsOwnReaderReads) {
  const fs::path p = good_log("reference", small_recording("a", 5'000'000));
  lcm::LogFile ref(p.string(), "r");
  formats::LcmLogReader mine(p);
  formats::LcmLogEvent e;
  int n = 0;
  while (const lcm::LogEvent* r = ref.readNextEvent()) {
    ASSERT_TRUE(mine.next(e));
    ASSERT_EQ(e.eventnum, r->eventnum);
    ASSERT_EQ(e.timestamp, r->timestamp);
    ASSERT_EQ(e.channel, r->channel);
    ASSERT_EQ(e.datalen, r->datalen);
    ASSERT_EQ(std::memcmp(e.data, r->data, static_cast<std::size_t>(r->datalen)), 0);
    ++n;
  }
  EXPECT_FALSE(mine.next(e));
  EXPECT_EQ(mine.damaged(), 0);
  EXPECT_GT(n, 80);
}

TEST(RecordingLogDamage, TruncatedLogGivesWhatItHoldsAndCountsTheCut) {
  const Recording rec = small_recording("cut", 5'000'000);
  auto bytes = read_bytes(good_log("full", rec));
  bytes.resize(bytes.size() * 6 / 10 + 13);
  const fs::path p = recording_temp("cut.lcmlog");
  write_bytes(p, bytes);
  std::int64_t skipped = 0;
  LogReadStats st;
  const auto recs = read_recordings_log(p, {}, &skipped, &st);
  EXPECT_EQ(skipped, 1);
  ASSERT_FALSE(st.damage.empty());
  EXPECT_NE(st.damage[0].find("cut short"), std::string::npos) << st.damage[0];
  std::size_t frames = 0;
  expect_subset_of(recs, rec, &frames);
  EXPECT_GT(frames, 5000u);
  EXPECT_LT(frames, 6500u);
}

TEST(RecordingLogDamage, CorruptedHeaderSkipsOneEventAndSplitsTheSession) {
  const Recording rec = small_recording("hdr", 5'000'000);
  auto bytes = read_bytes(good_log("hdr_src", rec));
  const auto events = walk(bytes);
  // The 20th raw block: its channel length becomes absurd.
  int seen = 0;
  std::size_t at = 0;
  for (const EventAt& e : events)
    if (e.channel == "NOISEMON_RAW" && ++seen == 20) at = e.offset;
  bytes[at + 20] = 0x7f;
  const fs::path p = recording_temp("hdr.lcmlog");
  write_bytes(p, bytes);
  std::int64_t skipped = 0;
  LogReadStats st;
  const auto recs = read_recordings_log(p, {}, &skipped, &st);
  EXPECT_EQ(skipped, 1);
  ASSERT_EQ(recs.size(), 2u);  // the block's frames are missing: two stretches, nothing invented
  EXPECT_EQ(st.pieces_split, 1);
  std::size_t frames = 0;
  expect_subset_of(recs, rec, &frames);
  EXPECT_EQ(frames, rec.frames() - 256);
}

TEST(RecordingLogDamage, DamagedDataLengthLosesOnlyThatEvent) {
  const Recording rec = small_recording("len", 5'000'000);
  auto bytes = read_bytes(good_log("len_src", rec));
  const auto events = walk(bytes);
  // The 25th raw block claims 1000 bytes more than it has: it would swallow the next event's start.
  int seen = 0;
  for (const EventAt& e : events)
    if (e.channel == "NOISEMON_RAW" && ++seen == 25) {
      const std::uint32_t len = e.datalen + 1000;
      for (int i = 0; i < 4; ++i)
        bytes[e.offset + 24 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(len >> (24 - 8 * i));
    }
  const fs::path p = recording_temp("len.lcmlog");
  write_bytes(p, bytes);
  std::int64_t skipped = 0;
  const auto recs = read_recordings_log(p, {}, &skipped);
  EXPECT_EQ(skipped, 1);
  std::size_t frames = 0;
  expect_subset_of(recs, rec, &frames);
  EXPECT_EQ(frames, rec.frames() - 256);
}

TEST(RecordingLogDamage, GarbageBetweenEventsIsSkippedAndCounted) {
  const Recording rec = small_recording("garbage", 5'000'000);
  auto bytes = read_bytes(good_log("garbage_src", rec));
  const auto events = walk(bytes);
  std::vector<std::uint8_t> junk(777);
  for (std::size_t i = 0; i < junk.size(); ++i) junk[i] = static_cast<std::uint8_t>(i * 37 + 11);
  bytes.insert(bytes.begin() + static_cast<std::ptrdiff_t>(events[30].offset), junk.begin(), junk.end());
  const fs::path p = recording_temp("garbage.lcmlog");
  write_bytes(p, bytes);
  std::int64_t skipped = 0;
  const auto recs = read_recordings_log(p, {}, &skipped);
  EXPECT_EQ(skipped, 1);
  ASSERT_EQ(recs.size(), 1u);
  std::size_t frames = 0;
  expect_subset_of(recs, rec, &frames);
  EXPECT_EQ(frames, rec.frames());  // no event lost
}

TEST(RecordingLogDamage, WrongFingerprintAndForeignTypesAreSkippedAndCounted) {
  const Recording rec = small_recording("types", 5'000'000);
  auto bytes = read_bytes(good_log("types_src", rec));
  const auto events = walk(bytes);
  // A raw block whose fingerprint is damaged.
  int seen = 0;
  for (const EventAt& e : events)
    if (e.channel == "NOISEMON_RAW" && ++seen == 7) bytes[e.data_offset + 3] ^= 0x5a;
  const fs::path p = recording_temp("types.lcmlog");
  write_bytes(p, bytes);
  {
    // Events of a foreign type on the raw and session channels, and of an unknown channel.
    lcm::LogFile log(p.string(), "a");
    noisemon::operating_point_t op{};
    std::vector<char> buf(static_cast<std::size_t>(op.getEncodedSize()));
    op.encode(buf.data(), 0, static_cast<int>(buf.size()));
    for (const char* ch : {"NOISEMON_RAW", "NOISEMON_SESSION", "SOMETHING_ELSE"}) {
      lcm::LogEvent e{0, 9'000'000, ch, static_cast<std::int32_t>(buf.size()), buf.data()};
      log.writeEvent(&e);
    }
  }
  std::int64_t skipped = 0;
  LogReadStats st;
  const auto recs = read_recordings_log(p, {}, &skipped, &st);
  EXPECT_EQ(skipped, 3);
  EXPECT_EQ(st.other_channels, 1);
  std::string all;
  for (const auto& d : st.damage) all += d + "\n";
  EXPECT_NE(all.find("on NOISEMON_RAW: does not decode as noisemon.raw_block_t"), std::string::npos) << all;
  EXPECT_NE(all.find("on NOISEMON_SESSION: does not decode as noisemon.session_t"), std::string::npos) << all;
  expect_subset_of(recs, rec);
}

TEST(RecordingLogDamage, BlocksThatContradictThemselvesAreNotUsed) {
  const Recording rec = small_recording("fields", 5'000'000);
  auto bytes = read_bytes(good_log("fields_src", rec));
  const auto events = walk(bytes);
  // Block A: first_index off by one (its utime no longer matches). Block B: a sample becomes NaN.
  // raw_block_t payload: fingerprint 8, utime 8, epoch 8, first_index 8, ... data from byte 49.
  int seen = 0;
  for (const EventAt& e : events) {
    if (e.channel != "NOISEMON_RAW") continue;
    ++seen;
    if (seen == 11) bytes[e.data_offset + 31] ^= 0x01;
    if (seen == 31) {
      const std::uint8_t nan_be[8] = {0x7f, 0xf8, 0, 0, 0, 0, 0, 0};
      std::memcpy(&bytes[e.data_offset + 49 + 8 * 5], nan_be, 8);
    }
  }
  const fs::path p = recording_temp("fields.lcmlog");
  write_bytes(p, bytes);
  std::int64_t skipped = 0;
  LogReadStats st;
  const auto recs = read_recordings_log(p, {}, &skipped, &st);
  EXPECT_EQ(skipped, 2);
  std::string all;
  for (const auto& d : st.damage) all += d + "\n";
  EXPECT_NE(all.find("utime does not match first_index"), std::string::npos) << all;
  EXPECT_NE(all.find("non-finite sample"), std::string::npos) << all;
  expect_subset_of(recs, rec);
  EXPECT_EQ(recs.size(), 3u);
}

TEST(RecordingLogDamage, LogWithoutSessionIsAnErrorNamingTheFile) {
  const fs::path p = recording_temp("nosession.lcmlog");
  {
    lcm::LogFile log(p.string(), "w");
    std::vector<char> junk(100, 'x');
    lcm::LogEvent e{0, 1, "NOISEMON_RAW", static_cast<std::int32_t>(junk.size()), junk.data()};
    log.writeEvent(&e);
  }
  for (const fs::path& f : {p, recording_temp("empty.lcmlog")}) {
    if (f != p) std::ofstream(f).close();
    try {
      read_recordings_log(f);
      ADD_FAILURE() << "no error for " << f;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(f.string() + ": no NOISEMON_SESSION message"), std::string::npos)
          << e.what();
    }
  }
}

TEST(Recording, SeveralRunsInOneLogComeBackAsSeveralRecordings) {
  const Recording a = small_recording("idle_mi12", 5'000'000);
  Recording b = small_recording("full_mi18", 9'000'000);
  b.info.mic_count = 0;
  b.info.mic_positions_m.clear();
  b.mics_pa.clear();
  const fs::path p = recording_temp("two.lcmlog");
  write_recordings_log(p, {a, b});
  LogReadStats st;
  const auto recs = read_recordings_log(p, {}, nullptr, &st);
  EXPECT_EQ(st.sessions, 2);
  ASSERT_EQ(recs.size(), 2u);
  EXPECT_EQ(recs[0].condition, "idle_mi12");
  EXPECT_EQ(recs[1].condition, "full_mi18");
  EXPECT_EQ(recs[1].info.mic_count, 0u);
  expect_subset_of({recs[0]}, a);
  EXPECT_EQ(recs[1].pressure_pa, b.pressure_pa);
  // The same epoch twice cannot be told apart: refused.
  EXPECT_THROW(write_recordings_log(recording_temp("same.lcmlog"), {a, a}), std::invalid_argument);
}
