// The comedi source end to end without a card: every acquisition is a pipe the test owns, written with exactly
// the bytes a card would deliver (16-bit analog codes, 32-bit counter values, scans interleaved in channel-list
// order), read by the source's own driver threads through the same read loops, decoders and assemblers as the
// device path. The 40 kHz output is checked against the analytic signals the bytes were made from:
//  - an engine turning at 1500 rpm with a 3.5 % speed ripple, a 0.25-degree encoder (position counter reset by
//    an index 37.5 degrees after a TDC, timestamps of an 80 MHz timebase) and a known pressure curve against
//    crank angle; the expected pressure and crank angle at each 40 kHz instant come from inverting the test's
//    own angle-time law, not from the source;
//  - sines of known level on the microphones;
// plus buffer overruns (EPIPE from the read function) restarting the acquisition with a count, the cam phase,
// and the errors for a missing device and a bad configuration.
#include "tests/drivers/comedi_fake_card.hpp"

#include <gtest/gtest.h>

#include <cstdio>

#include "drivers/timed_stream.hpp"

// In a namespace of its own: the using-directive must not reach the other sources of its unity batch.
namespace comedi_source_tests {
using namespace comedi_fake;

namespace {

// Seconds since the acquisition origin of 40 kHz frame k.
double since_origin(std::int64_t k, std::int64_t origin_us) {
  return static_cast<double>(k) / 40000.0 - origin_us * 1e-6;
}

double angle_error(double a, double b) { return std::remainder(a - b, 720.0); }

struct PressureCheck {
  std::size_t frames = 0;
  double max_p_err = 0, rms_p_err = 0, max_crank_err = 0;
  bool contiguous = true;
};

PressureCheck check_pressure(const Harness& h, bool second_peak, std::int64_t origin_us, double t_from, double t_to) {
  PressureCheck c;
  std::int64_t previous = -1;
  for (const auto& [k, v] : h.pressure_frames) {
    const double t = since_origin(k, origin_us);
    if (t < t_from || t > t_to) continue;
    if (previous >= 0 && k != previous + 1) c.contiguous = false;
    previous = k;
    const double theta = theta_at(t);
    const double e = v[0] - pressure_pa(theta, second_peak);
    c.max_p_err = std::max(c.max_p_err, std::abs(e));
    c.rms_p_err += e * e;
    c.max_crank_err = std::max(c.max_crank_err, std::abs(angle_error(v[1], wrap720(theta))));
    EXPECT_GE(v[1], -360.0);
    EXPECT_LT(v[1], 360.0);
    ++c.frames;
  }
  c.rms_p_err = c.frames ? std::sqrt(c.rms_p_err / c.frames) : 0;
  return c;
}

}  // namespace

class ComediSourcePipes : public ::testing::TestWithParam<EngineSetup> {};

TEST_P(ComediSourcePipes, CardBytesBecomeTheAnalytic40kHzStreams) {
  const EngineSetup setup = GetParam();
  Harness h(source_config(setup));
  ASSERT_EQ(h.acquisitions.size(), setup.separate_timestamp ? 4u : 3u);
  const std::size_t edges = h.run_engine(setup);

  for (const auto& t : h.source->thread_status())
    EXPECT_NE(t.state, nd::ThreadState::kFailed) << t.name << ": " << t.error;
  EXPECT_EQ(h.counter("comedi.encoder.edges"), static_cast<std::int64_t>(edges));
  EXPECT_EQ(h.counter("comedi.encoder.errors"), 0);
  EXPECT_EQ(h.counter("comedi.encoder.phase_corrections"), 0);
  EXPECT_EQ(h.counter("comedi.pressure.overruns"), 0);

  // Output starts once the phase is known (two TDCs seen) and, with a relative sensor, the first pegging at
  // intake BDC has been done: at most one revolution + one cycle after the start.
  ASSERT_FALSE(h.pressure_frames.empty());
  const double first_t = since_origin(h.pressure_frames.begin()->first, kEdgeOriginUs);
  EXPECT_LT(first_t, (360.0 + 720.0 + 60.0) / kOmega * 1.05);
  const PressureCheck c = check_pressure(h, false, kEdgeOriginUs, first_t + 0.002, setup.duration_s - 0.005);
  std::printf(
      "pressure: %zu frames from t = %.1f ms, max |error| %.0f Pa, rms %.0f Pa (peak 6.1e6 Pa); crank max |error| %.2e "
      "deg\n",
      c.frames, 1e3 * first_t, c.max_p_err, c.rms_p_err, c.max_crank_err);
  EXPECT_GT(c.frames, static_cast<std::size_t>(0.4 * 40000));
  EXPECT_TRUE(c.contiguous);
  // Budget: 16-bit quantisation (+-0.15 mV at the card = +-305 Pa through 50 mV/bar, also in the pegging
  // mean) and 12.5 ns timestamp resolution; the resampler itself is ~1e-5 relative.
  EXPECT_LT(c.max_p_err, 2000.0);
  EXPECT_LT(c.rms_p_err, 600.0);
  EXPECT_LT(c.max_crank_err, 1e-3);

  // The crank-angle stream: every edge on the encoder's 0.25 deg grid (the index at 37.5 deg), its pressure the
  // analytic one there within the same quantisation budget, in order, each block begun at or before its edges.
  EXPECT_EQ(h.source->info().pressure_angle_step_deg, kResolution);
  ASSERT_GT(h.edges.size(), 1000u);
  double max_edge_err = 0, max_off_grid = 0;
  for (const auto& [first_index, crank, pa] : h.edges) {
    max_off_grid = std::max(max_off_grid, std::abs(std::remainder(crank - kIndexDeg, kResolution)));
    max_edge_err = std::max(max_edge_err, std::abs(pa - pressure_pa(crank)));
  }
  std::printf("crank-angle stream: %zu edges, off the grid by at most %.1e deg, pressure max |error| %.0f Pa\n",
              h.edges.size(), max_off_grid, max_edge_err);
  EXPECT_LT(max_off_grid, 1e-9);
  EXPECT_LT(max_edge_err, 2000.0);

  // Microphones: each tone at its instant, from the first frame after the resampler settled.
  ASSERT_FALSE(h.mic_frames.empty());
  EXPECT_EQ(h.mic_frames.begin()->first, 40 + nd::TimedStreamAssembler::kSettleFrames);  // origin at frame 40
  double max_err[3] = {0, 0, 0}, ms[3] = {0, 0, 0};
  std::size_t n = 0;
  for (const auto& [k, v] : h.mic_frames) {
    const double t = since_origin(k, kMicOriginUs);
    if (t > setup.duration_s - 0.005) break;
    for (std::size_t c = 0; c < 3; ++c) {
      max_err[c] = std::max(max_err[c], std::abs(v[c] - tone(c, t)));
      ms[c] += v[c] * v[c];
    }
    ++n;
  }
  ASSERT_GT(n, 20000u);
  for (std::size_t c = 0; c < 3; ++c) {
    const double level = 10.0 * std::log10(ms[c] / n / (20e-6 * 20e-6));
    const double expected = 20.0 * std::log10(kTones[c].amplitude_pa / std::sqrt(2.0) / 20e-6);
    std::printf("mic %zu: %.0f Hz, level %.3f dB (expected %.3f), max |error| %.2e Pa\n", c, kTones[c].hz, level,
                expected, max_err[c]);
    EXPECT_NEAR(level, expected, 0.02);  // the 41-step sine of mic 1 loses 0.010 dB to 16-bit rounding alone
    // +-1 V range: 30.5 uV steps = 0.6..2.4 mPa at these sensitivities, plus the resampler's ~3e-5.
    EXPECT_LT(max_err[c], 3e-3);
  }
}

INSTANTIATE_TEST_SUITE_P(
    Wiring, ComediSourcePipes,
    ::testing::Values(EngineSetup{},  // charge chain pegged, absolute 24-bit timestamps wrapping twice
                      EngineSetup{.charge_chain = false,
                                  .period_timestamps = true,
                                  .separate_timestamp = true,
                                  .timestamp_bits = 32}),
    [](const auto& info) {
      return info.param.separate_timestamp ? std::string("VoltageChainPeriodTimestamps")
                                           : std::string("ChargeChainPeggedWrappingTimestamps");
    });

// A charge chain whose offset moves by 1 bar at every gas-exchange TDC (+-0.5 bar about the drift): each cycle is
// pegged with the offset measured at its own intake BDC, over the whole cycle, so the pressure stays within the
// quantisation budget everywhere; pegging from the window on would leave -360 ... -175 deg 1 bar off.
TEST(ComediSource, PeggingHoldsForTheWholeCycleItWasMeasuredIn) {
  EngineSetup setup{.offset_step_bar = 0.5};
  Harness h(source_config(setup));
  h.run_engine(setup);
  ASSERT_FALSE(h.pressure_frames.empty());
  const double first_t = since_origin(h.pressure_frames.begin()->first, kEdgeOriginUs);
  const PressureCheck c = check_pressure(h, false, kEdgeOriginUs, first_t + 0.002, setup.duration_s - 0.005);
  std::printf("offset moving 1 bar a cycle: %zu frames, max |error| %.0f Pa\n", c.frames, c.max_p_err);
  EXPECT_GT(c.frames, static_cast<std::size_t>(0.3 * 40000));
  EXPECT_LT(c.max_p_err, 2000.0);
  // The edges too, but for the last cycle's before its intake BDC: at the stop they go out with the offset in hand.
  double max_edge_err = 0;
  std::size_t checked = 0;
  for (const auto& [first_index, crank, pa] : h.edges) {
    if (since_origin(static_cast<std::int64_t>(first_index), kEdgeOriginUs) > setup.duration_s - 720.0 / kOmega)
      continue;
    max_edge_err = std::max(max_edge_err, std::abs(pa - pressure_pa(crank)));
    ++checked;
  }
  EXPECT_GT(checked, 10000u);
  EXPECT_LT(max_edge_err, 2000.0);
}

TEST(ComediSource, CamTellsFiringTdcWhenBothTdcsLookAlike) {
  // The same peak at both TDCs: the pressure cannot tell them apart, the cam sensor can.
  EngineSetup setup{.duration_s = 0.4, .charge_chain = false, .cam = true, .second_peak = true};
  Harness h(source_config(setup));
  h.run_engine(setup);
  ASSERT_FALSE(h.pressure_frames.empty());
  const double first_t = since_origin(h.pressure_frames.begin()->first, kEdgeOriginUs);
  // Locked at the first cam edge (-100 deg, i.e. 190 deg after the start).
  EXPECT_LT(first_t, 200.0 / kOmega);
  const PressureCheck c = check_pressure(h, true, kEdgeOriginUs, first_t + 0.002, setup.duration_s - 0.005);
  EXPECT_LT(c.max_crank_err, 1e-3);  // 0 deg is the firing TDC the cam says, not the other one
  EXPECT_LT(c.max_p_err, 2000.0);

  // Without the cam, the look-alike TDCs never give a phase: no pressure output rather than a guess.
  nd::comedi::ComediSourceConfig cfg = source_config(setup);
  cfg.phase = nd::comedi::PhaseSource::kPressure;
  Harness guess(cfg);
  const std::size_t edges = guess.run_engine(setup);
  EXPECT_TRUE(guess.pressure_frames.empty());
  EXPECT_EQ(guess.counter("comedi.encoder.edges_before_lock"), static_cast<std::int64_t>(edges));
}

TEST(ComediSource, MicOverrunRestartsWithBackoffIsCountedAndResumes) {
  EngineSetup setup{.duration_s = 0.3, .charge_chain = false};
  Harness h(source_config(setup));
  EdgeBytes e = engine_bytes(setup);
  h.by_device("/dev/test-pressure", 0).feed(std::move(e.pressure));
  h.by_device("/dev/test-counter", 11).feed(std::move(e.encoder));
  PipeAcquisition& mic = h.by_device("/dev/test-mics", 0);
  // 0.1 s of scans, then the card overruns; it is re-armed 50 ms later (the new origin) and delivers 0.15 s more.
  const std::vector<std::byte> before = mic_bytes(0.1);
  mic.epipe_at = before.size();
  mic.restart_shift_us = 150'000;
  std::vector<std::byte> all = before;
  const std::vector<std::byte> after = mic_bytes(0.15);
  all.insert(all.end(), after.begin(), after.end());
  mic.feed(std::move(all));
  h.run();

  EXPECT_EQ(h.counter("comedi.mics.overruns"), 1);
  EXPECT_EQ(h.counter("comedi.mics.restarts"), 1);
  EXPECT_EQ(mic.restarts.load(), 1);
  for (const auto& t : h.source->thread_status())
    EXPECT_NE(t.state, nd::ThreadState::kFailed) << t.name << ": " << t.error;
  // Before the overrun: on the first origin; after: on the new one, after a gap, the tone again in phase with
  // the restarted card's scan 0.
  const std::int64_t restart_frame = (kMicOriginUs + 150'000) / 25;
  std::size_t n_before = 0, n_after = 0;
  double max_err = 0;
  for (const auto& [k, v] : h.mic_frames) {
    const bool after_restart = k >= restart_frame;
    const double t = since_origin(k, after_restart ? kMicOriginUs + 150'000 : kMicOriginUs);
    if (t > (after_restart ? 0.145 : 0.095)) continue;  // the ends of each stretch lack input to resample
    max_err = std::max(max_err, std::abs(v[0] - tone(0, t)));
    ++(after_restart ? n_after : n_before);
  }
  EXPECT_GT(n_before, 3000u);
  EXPECT_GT(n_after, 5000u);
  EXPECT_LT(max_err, 3e-3);
  EXPECT_EQ(h.mic_frames.count(restart_frame + nd::TimedStreamAssembler::kSettleFrames - 1), 0u);
  EXPECT_EQ(h.mic_frames.count(restart_frame + nd::TimedStreamAssembler::kSettleFrames), 1u);
}

TEST(ComediSource, EncoderOverrunRestartsTheWholeEdgeGroup) {
  EngineSetup setup{.duration_s = 0.5, .charge_chain = false};
  Harness h(source_config(setup));
  PipeAcquisition& pressure = h.by_device("/dev/test-pressure", 0);
  PipeAcquisition& encoder = h.by_device("/dev/test-counter", 11);
  // The counter overruns after 0.2 s of edges; both subdevices are re-armed and start again at the first edge
  // after t = 0.25 s (their new origin), timestamps counting from there.
  EngineSetup first = setup;
  first.duration_s = 0.2;
  EdgeBytes a = engine_bytes(first);
  encoder.epipe_at = a.encoder.size();
  pressure.hold_at = a.pressure.size();
  constexpr std::int64_t kShift = 250'000;
  encoder.restart_shift_us = pressure.restart_shift_us = kShift;
  // After the restart: edges from t = 0.25 s, timestamps relative to the new origin.
  EdgeBytes b;
  {
    const double t_from = kShift * 1e-6;
    const EdgeBytes later = engine_bytes(setup, t_from);
    // Re-stamp relative to the new origin: subtract the origin's ticks from each absolute stamp (24-bit wrap).
    b.pressure = later.pressure;
    const std::uint64_t mask = (1ULL << setup.timestamp_bits) - 1;
    const auto origin_ticks = static_cast<std::uint64_t>(std::floor(t_from * kTimebase));
    for (std::size_t i = 0; i + 8 <= later.encoder.size(); i += 8) {
      std::uint32_t position, stamp;
      std::memcpy(&position, &later.encoder[i], 4);
      std::memcpy(&stamp, &later.encoder[i + 4], 4);
      append(b.encoder, position);
      append(b.encoder, static_cast<std::uint32_t>((stamp - origin_ticks) & mask));
    }
  }
  // The pressure subdevice's bytes from before the overrun that were never read are lost with the cancel; here
  // its pipe simply carries the pre-overrun scans then the post-restart ones.
  std::vector<std::byte> p = a.pressure, enc = a.encoder;
  p.insert(p.end(), b.pressure.begin(), b.pressure.end());
  enc.insert(enc.end(), b.encoder.begin(), b.encoder.end());
  pressure.feed(std::move(p));
  encoder.feed(std::move(enc));
  h.by_device("/dev/test-mics", 0).feed(mic_bytes(setup.duration_s));
  h.run();

  EXPECT_EQ(h.counter("comedi.pressure.overruns"), 1);
  EXPECT_EQ(h.counter("comedi.pressure.restarts"), 1);
  EXPECT_EQ(pressure.restarts.load(), 1);  // the pressure input was re-armed with the counter
  EXPECT_EQ(encoder.restarts.load(), 1);
  EXPECT_GE(pressure.cancels.load(), 1);
  for (const auto& t : h.source->thread_status())
    EXPECT_NE(t.state, nd::ThreadState::kFailed) << t.name << ": " << t.error;
  // Both stretches match the engine; times after the restart are on the new origin's clock, which is the
  // same clock here (origin shifted by exactly the time the test skipped).
  const PressureCheck c = check_pressure(h, false, kEdgeOriginUs, 0.0, setup.duration_s - 0.005);
  EXPECT_LT(c.max_p_err, 2000.0);
  EXPECT_LT(c.max_crank_err, 1e-3);
  EXPECT_FALSE(c.contiguous);  // a gap where the acquisition was down
  std::size_t after = 0;
  for (const auto& [k, v] : h.pressure_frames) after += since_origin(k, kEdgeOriginUs) > 0.25 ? 1 : 0;
  EXPECT_GT(after, static_cast<std::size_t>(0.1 * 40000));  // locked again after the restart
}

// Turning, and at rest (the pressure on the card's timer): the device the source could not open is named.
TEST(ComediSource, MissingDeviceIsAnErrorNamingIt) {
  const std::string path = "/dev/comedi-noisemon-test-missing";
  for (const bool at_rest : {false, true}) {
    nd::comedi::ComediSourceConfig c = source_config(EngineSetup{});
    c.pressure.device = path;
    c.at_rest = at_rest;
    try {
      nd::comedi::make_comedi_source(c);
      ADD_FAILURE() << "a missing device opened (at rest: " << at_rest << ")";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
}

TEST(ComediSource, ConfigurationErrorsNameTheField) {
  auto error = [](const nd::comedi::ComediSourceConfig& c) -> std::string {
    try {
      nd::comedi::comedi_acquisitions(c);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  nd::comedi::ComediSourceConfig c = source_config(EngineSetup{});
  c.pressure.sensitivity_mv_per_bar = 20.0;  // as well as the charge chain
  EXPECT_NE(error(c).find("comedi.pressure"), std::string::npos);
  c = source_config(EngineSetup{});
  c.encoder.subdevice = -1;
  EXPECT_NE(error(c).find("comedi.encoder.subdevice"), std::string::npos);
  c = source_config(EngineSetup{});
  c.mics.sensitivity_mv_per_pa.pop_back();
  EXPECT_NE(error(c).find("comedi.mics.sensitivity_mv_per_pa"), std::string::npos);
  c = source_config(EngineSetup{});
  c.phase = nd::comedi::PhaseSource::kCam;
  EXPECT_NE(error(c).find("cam_channel"), std::string::npos);
  c = source_config(EngineSetup{});
  c.pressure.offset_bar = 0.37;  // a charge chain has no absolute zero
  EXPECT_NE(error(c).find("comedi.pressure: offset_bar applies to a voltage-output chain"), std::string::npos)
      << error(c);
  c = source_config(EngineSetup{});
  c.pressure.sensitivity_pc_per_bar = c.pressure.amplifier_mv_per_pc = 0.0;
  c.pressure.sensitivity_mv_per_bar = 20.0;
  c.pressure.offset_bar = 0.37;
  EXPECT_DOUBLE_EQ(nd::comedi::comedi_acquisitions(c)[0].channels[0].si_offset, 0.37e5);  // in Pa, as the scan's SI
  // The acquisitions built from a good configuration: channel lists and clocks as wired.
  const auto a = nd::comedi::comedi_acquisitions(source_config(EngineSetup{.cam = true}));
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[0].clock, nd::comedi::ScanClock::kExternal);
  ASSERT_EQ(a[0].channels.size(), 2u);                                        // pressure, cam
  EXPECT_DOUBLE_EQ(a[0].channels[0].si_per_volt, 1e5 / (10.0 * 5.0 * 1e-3));  // Pa per V of 50 mV/bar
  EXPECT_EQ(a[0].channels[1].channel, 3u);
  EXPECT_EQ(a[1].subdevice, 11);
  ASSERT_EQ(a[1].channels.size(), 2u);  // position, timestamp
  EXPECT_TRUE(a[1].channels[0].raw_counts && a[1].channels[1].raw_counts);
  EXPECT_EQ(a[2].clock, nd::comedi::ScanClock::kTimed);
  EXPECT_DOUBLE_EQ(a[2].channels[1].si_per_volt, 1.0 / 12.5e-3);
}

}  // namespace comedi_source_tests
