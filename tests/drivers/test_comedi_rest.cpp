// The comedi source with the engine at rest (ComediSourceConfig::at_rest) through the fake card's pipes, read by the
// source's own driver threads as a card's descriptors would be: the pressure channel on the card's timer comes out as
// the 40 kHz pressure stream with the crank angle NaN, converted with the chain's sensitivity and offset_bar exactly
// as a hand computation from the card's raw codes gives it, and placed in time on the card's scan clock; the
// encoder's edges, when the engine turns after all, come out as a speed; the rest scan rate is validated naming its
// field. (A missing device at rest: test_comedi_source.cpp, beside the one of the turning engine.)
#include <gtest/gtest.h>

#include <cmath>

#include "drivers/comedi/comedi_rest.hpp"
#include "drivers/timed_stream.hpp"
#include "tests/drivers/comedi_fake_card.hpp"

namespace rest_card = comedi_fake;  // (no using-directive: a unity batch shares this file's scope)
namespace nd = noisemon::drivers;

namespace {

constexpr double kRestMvPerBar = 100.0;  // the voltage chain of source_config(charge_chain = false)
constexpr double kRestOffsetBar = 0.37;  // what the chain reads above the truth: offset_bar takes it off
constexpr double kRestRateHz = 20000.0;

// The fake card at rest: a voltage chain zeroed with kRestOffsetBar, the pressure scanned at kRestRateHz.
nd::comedi::ComediSourceConfig rest_config() {
  nd::comedi::ComediSourceConfig c = rest_card::source_config(rest_card::EngineSetup{.charge_chain = false});
  c.pressure.offset_bar = kRestOffsetBar;
  c.pressure.rest_scan_rate_hz = kRestRateHz;
  c.at_rest = true;
  return c;
}

// The card's 16-bit codes (range 0, +-10 V) of the pressure `bar_at(t)` read kRestOffsetBar high, for `seconds`.
template <class Pressure>
std::vector<std::byte> rest_pressure_bytes(double seconds, Pressure bar_at) {
  std::vector<std::byte> out;
  const auto scans = static_cast<std::size_t>(seconds * kRestRateHz);
  for (std::size_t n = 0; n < scans; ++n)
    rest_card::append(out, rest_card::code16((bar_at(n / kRestRateHz) + kRestOffsetBar) * kRestMvPerBar * 1e-3, 0));
  return out;
}

// Pa of one raw code, by hand: the code's volts over the range, through 100 mV/bar, less offset_bar.
double pa_of_code(std::uint16_t code) {
  const double volts = rest_card::kRangeLo[0] + code * (rest_card::kRangeHi[0] - rest_card::kRangeLo[0]) / 65535.0;
  return 1e5 * (volts / (kRestMvPerBar * 1e-3) - kRestOffsetBar);
}

}  // namespace

TEST(ComediRest, AcquisitionsPutThePressureOnTheTimerWithItsConversion) {
  nd::comedi::ComediSourceConfig c = rest_config();
  c.pressure.cam_channel = 3;          // left out at rest
  c.encoder.timestamp_subdevice = 12;  // not opened at rest: the edges are counted, not timed
  const auto a = nd::comedi::comedi_acquisitions(c);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[0].clock, nd::comedi::ScanClock::kTimed);
  EXPECT_DOUBLE_EQ(a[0].scan_rate_hz, kRestRateHz);
  ASSERT_EQ(a[0].channels.size(), 1u);
  nd::comedi::ComediSourceConfig turning = c;
  turning.at_rest = false;
  const auto edge = nd::comedi::comedi_acquisitions(turning);
  EXPECT_DOUBLE_EQ(a[0].channels[0].si_per_volt, edge[0].channels[0].si_per_volt);  // as the edge-clocked scan
  EXPECT_DOUBLE_EQ(a[0].channels[0].si_offset, kRestOffsetBar * 1e5);
  EXPECT_EQ(a[1].subdevice, 11);
  EXPECT_EQ(a[1].clock, nd::comedi::ScanClock::kExternal);
  EXPECT_EQ(a[2].clock, nd::comedi::ScanClock::kTimed);
  EXPECT_EQ(a[2].device_path, "/dev/test-mics");
}

TEST(ComediRest, ScanRateErrorsNameTheField) {
  for (double hz : {12345.5, 100.0, 2e6, std::nan("")}) {
    nd::comedi::ComediSourceConfig c = rest_config();
    c.pressure.rest_scan_rate_hz = hz;
    try {
      nd::comedi::comedi_acquisitions(c);
      ADD_FAILURE() << hz << " Hz accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("comedi.pressure.rest_scan_rate_hz"), std::string::npos) << e.what();
    }
  }
}

TEST(ComediRest, PressureIsTheCardsCodesThroughSensitivityAndOffset) {
  rest_card::Harness h(rest_config());
  ASSERT_EQ(h.acquisitions.size(), 3u);
  constexpr double kBar = 1.0132;
  const std::vector<std::byte> bytes = rest_pressure_bytes(0.3, [](double) { return kBar; });
  std::uint16_t code = 0;
  std::memcpy(&code, bytes.data(), sizeof code);
  const double expected = pa_of_code(code);
  EXPECT_NEAR(expected, kBar * 1e5, 200.0);  // one code is 3 mbar through 100 mV/bar
  h.by_device("/dev/test-pressure", 0).feed(bytes);
  h.by_device("/dev/test-mics", 0).feed(rest_card::mic_bytes(0.3));
  h.run();

  for (const auto& t : h.source->thread_status())
    EXPECT_NE(t.state, nd::ThreadState::kFailed) << t.name << ": " << t.error;
  EXPECT_EQ(h.source->info().pressure_angle_step_deg, 0.0);  // no crank-angle stream at rest
  EXPECT_TRUE(h.edges.empty());
  EXPECT_EQ(h.counter("comedi.encoder.edges"), 0);
  ASSERT_FALSE(h.pressure_frames.empty());
  // The card's scan 0 at its origin (frame 40); the resampler's settling left out.
  EXPECT_EQ(h.pressure_frames.begin()->first, rest_card::kMicOriginUs / 25 + nd::TimedStreamAssembler::kSettleFrames);
  double max_error = 0;
  std::size_t n = 0;
  for (const auto& [k, v] : h.pressure_frames) {
    ASSERT_EQ(v.size(), 2u);
    EXPECT_TRUE(std::isnan(v[1])) << "crank angle at frame " << k;
    if (static_cast<double>(k) / 40000.0 > 0.29) continue;  // the last scans lack input after them to resample
    max_error = std::max(max_error, std::abs(v[0] - expected));
    ++n;
  }
  std::printf("at rest: %zu frames, max |error| %.3f Pa against the hand computation %.1f Pa\n", n, max_error,
              expected);
  EXPECT_GT(n, static_cast<std::size_t>(0.25 * 40000));
  EXPECT_LT(max_error, 1.0);  // single-precision resampling of a constant: ~1e-7 of it
  nd::OperatingPoint op;
  while (h.op.read(&op, 1) == 1) EXPECT_EQ(op.speed_rpm, 0.0);  // no edge: at rest
}

TEST(ComediRest, PressureIsPlacedOnTheCardsScanClock) {
  rest_card::Harness h(rest_config());
  auto bar_at = [](double t) { return 1.5 + 0.5 * std::sin(2.0 * rest_card::kPi * 50.0 * t); };
  h.by_device("/dev/test-pressure", 0).feed(rest_pressure_bytes(0.3, bar_at));
  h.by_device("/dev/test-mics", 0).feed(rest_card::mic_bytes(0.3));
  h.run();
  double max_error = 0;
  std::size_t n = 0;
  for (const auto& [k, v] : h.pressure_frames) {
    const double t = static_cast<double>(k) / 40000.0 - rest_card::kMicOriginUs * 1e-6;
    if (t > 0.29) continue;
    max_error = std::max(max_error, std::abs(v[0] - 1e5 * bar_at(t)));
    ++n;
  }
  EXPECT_GT(n, static_cast<std::size_t>(0.25 * 40000));
  EXPECT_LT(max_error, 400.0);  // half a code (153 Pa) and the resampler's ripple; 25 us late would be 790 Pa
}

TEST(ComediRest, ATurningEngineShowsAsSpeed) {
  rest_card::Harness h(rest_config());
  rest_card::EngineSetup turning{.duration_s = 0.2, .charge_chain = false};
  rest_card::EdgeBytes e = rest_card::engine_bytes(turning);
  rest_card::PipeAcquisition& encoder = h.by_device("/dev/test-counter", 11);
  encoder.feed(std::move(e.encoder));
  h.by_device("/dev/test-pressure", 0).feed(rest_pressure_bytes(0.3, [](double) { return 1.0; }));
  h.by_device("/dev/test-mics", 0).feed(rest_card::mic_bytes(0.3));
  h.source->start(nd::Streams{&h.pressure, &h.mics, &h.op, &h.angle});
  // The speed goes out every 100 ms of host time: wait for two windows after the edges were read.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (encoder.delivered.load() < encoder.total && std::chrono::steady_clock::now() < deadline) {
    h.drain();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  for (int i = 0; i < 50; ++i) {
    h.drain();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  h.source->stop();
  EXPECT_EQ(h.counter("comedi.encoder.edges"), static_cast<std::int64_t>(e.edges));
  double fastest = 0;
  std::size_t ops = 0;
  nd::OperatingPoint op;
  while (h.op.read(&op, 1) == 1) {
    fastest = std::max(fastest, op.speed_rpm);
    EXPECT_TRUE(std::isnan(op.load_nm));  // the card knows the speed alone
    ++ops;
  }
  EXPECT_GE(ops, 1u);
  EXPECT_GT(fastest, 1.0);  // calibrate's and check's threshold of a turning engine
}
