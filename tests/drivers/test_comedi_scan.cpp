// Tests of the comedi scan decoder. References are hand-computed here: raw codes chosen so comedi_to_phys /
// comedi_to_physical give exact voltages, and sensor chains worked through by unit (V -> mV -> pC -> bar -> Pa).
// Streams of random raw codes are checked against the conversion formulas written out in the test, whatever
// way the bytes are split, including through a real pipe read by the device path's read loop.
#include "drivers/comedi/comedi_scan.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <random>
#include <vector>

#include "drivers/comedi/comedi_device.hpp"

namespace nd = noisemon::drivers;

namespace {

template <class T>
std::vector<std::byte> bytes_of(const std::vector<T>& raw) {
  std::vector<std::byte> out(raw.size() * sizeof(T));
  std::memcpy(out.data(), raw.data(), out.size());
  return out;
}

std::vector<double> decode_all(nd::comedi::ScanDecoder& d, const std::vector<std::byte>& b) {
  std::vector<double> out;
  d.feed(b.data(), b.size(), [&](const double* v) { out.insert(out.end(), v, v + d.channels()); });
  return out;
}

}  // namespace

TEST(ComediSensitivity, UnitChains) {
  EXPECT_DOUBLE_EQ(nd::comedi::microphone_pa_per_volt(50.0), 20.0);                  // 1 V / 50 mV/Pa = 20 Pa
  EXPECT_DOUBLE_EQ(nd::comedi::pressure_pa_per_volt(20.0), 50.0 * 1e5);              // 1 V / 20 mV/bar = 50 bar
  EXPECT_DOUBLE_EQ(nd::comedi::charge_pressure_pa_per_volt(2.0, 10.0), 50.0 * 1e5);  // 1000 mV/10 = 100 pC / 2 = 50 bar
  EXPECT_THROW(nd::comedi::microphone_pa_per_volt(0.0), std::invalid_argument);
  EXPECT_THROW(nd::comedi::charge_pressure_pa_per_volt(2.0, -1.0), std::invalid_argument);
}

TEST(ComediScan, Linear16BitHandValues) {
  // 12-bit card in sampl_t: range [-5, 5] V, maxdata 4095; codes 819, 2457 are -3 V and +1 V exactly.
  // Channel 0: microphone 50 mV/Pa; channel 1: raw volts.
  nd::comedi::ScanDecoder d(nd::comedi::SampleWidth::k16Bit,
                            {nd::comedi::linear_conversion(-5, 5, 4095, nd::comedi::microphone_pa_per_volt(50)),
                             nd::comedi::linear_conversion(-5, 5, 4095, 1.0)});
  const auto v = decode_all(d, bytes_of(std::vector<std::uint16_t>{819, 2457, 2457, 4095, 0, 819}));
  ASSERT_EQ(v.size(), 6u);
  EXPECT_NEAR(v[0], -60.0, 1e-12);  // -3 V * 20 Pa/V
  EXPECT_NEAR(v[1], 1.0, 1e-12);
  EXPECT_NEAR(v[2], 20.0, 1e-12);
  EXPECT_NEAR(v[3], 5.0, 1e-12);
  EXPECT_NEAR(v[4], -100.0, 1e-12);
  EXPECT_NEAR(v[5], -3.0, 1e-12);
}

TEST(ComediScan, Linear32BitHandValues) {
  // lsampl_t, range [-10, 10] V, maxdata 2^32-1 = 5 * 858993459: code 858993459 is -6 V, 3x that is +2 V.
  // Pressure transducer at 20 mV/bar: 2 V = 100 bar = 1e7 Pa.
  nd::comedi::ScanDecoder d(
      nd::comedi::SampleWidth::k32Bit,
      {nd::comedi::linear_conversion(-10, 10, 4294967295u, nd::comedi::pressure_pa_per_volt(20))});
  const auto v = decode_all(d, bytes_of(std::vector<std::uint32_t>{858993459u, 2576980377u, 4294967295u}));
  ASSERT_EQ(v.size(), 3u);
  EXPECT_NEAR(v[0], -3e7, 1e-6);
  EXPECT_NEAR(v[1], 1e7, 1e-6);
  EXPECT_NEAR(v[2], 5e7, 1e-6);
}

TEST(ComediScan, PressureOffsetIsSubtractedInBarAfterTheConversion) {
  // 12-bit card, range [-5, 5] V, maxdata 4095: codes 819, 2457, 2048 are -3 V, +1 V and 5 / 4095 V.
  // Voltage-output transducer at 20 mV/bar (50 bar/V) reading 0.37 bar high: +1 V is 50 bar on the scale, 49.63 bar
  // true; -3 V is -150.37 bar; 5 / 4095 V is 0.0610500 bar on the scale, -0.3089500 bar true.
  nd::comedi::ScanDecoder d(nd::comedi::SampleWidth::k16Bit,
                            {nd::comedi::linear_conversion(-5, 5, 4095, nd::comedi::pressure_pa_per_volt(20), 0.37e5)});
  const auto v = decode_all(d, bytes_of(std::vector<std::uint16_t>{2457, 819, 2048}));
  ASSERT_EQ(v.size(), 3u);
  EXPECT_NEAR(v[0], 49.63e5, 1e-6);
  EXPECT_NEAR(v[1], -150.37e5, 1e-6);
  EXPECT_NEAR(v[2], (50.0 * 5.0 / 4095.0 - 0.37) * 1e5, 1e-6);
  // The soft calibration's polynomial takes the same offset: 0.5 + 1e-3 x at x = 1000 is 1.5 V = 75 bar - 0.37.
  const double c[] = {0.5, 1e-3};
  nd::comedi::ScanDecoder p(
      nd::comedi::SampleWidth::k16Bit,
      {nd::comedi::polynomial_conversion(c, 1, 32768.0, nd::comedi::pressure_pa_per_volt(20), 0.37e5)});
  const auto w = decode_all(p, bytes_of(std::vector<std::uint16_t>{33768}));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NEAR(w[0], 74.63e5, 1e-6);
}

TEST(ComediScan, PolynomialHandValues) {
  // Soft calibration 0.5 + 1e-3 x + 1e-8 x^2 with x = raw - 32768: raw 33768 -> 1.51 V, 31768 -> -0.49 V.
  // Piezo 2 pC/bar behind a 10 mV/pC charge amplifier: 1.51 V -> 151 pC -> 75.5 bar.
  const double c16[] = {0.5, 1e-3, 1e-8};
  nd::comedi::ScanDecoder d16(
      nd::comedi::SampleWidth::k16Bit,
      {nd::comedi::polynomial_conversion(c16, 2, 32768.0, nd::comedi::charge_pressure_pa_per_volt(2, 10))});
  const auto v16 = decode_all(d16, bytes_of(std::vector<std::uint16_t>{33768, 31768, 32768}));
  ASSERT_EQ(v16.size(), 3u);
  EXPECT_NEAR(v16[0], 75.5e5, 1e-6);
  EXPECT_NEAR(v16[1], -24.5e5, 1e-6);
  EXPECT_NEAR(v16[2], 25e5, 1e-6);

  // Cubic, 32-bit: 1e-6 x + 1e-18 x^3 at x = 1e6 is 2 V; microphone 2 mV/Pa -> 1000 Pa.
  const double c32[] = {0.0, 1e-6, 0.0, 1e-18};
  nd::comedi::ScanDecoder d32(nd::comedi::SampleWidth::k32Bit,
                              {nd::comedi::polynomial_conversion(c32, 3, 0.0, nd::comedi::microphone_pa_per_volt(2))});
  const auto v32 = decode_all(d32, bytes_of(std::vector<std::uint32_t>{1000000u, 2000000u}));
  ASSERT_EQ(v32.size(), 2u);
  EXPECT_NEAR(v32[0], 1000.0, 1e-9);
  EXPECT_NEAR(v32[1], (2.0 + 8.0) * 500.0, 1e-9);
}

TEST(ComediScan, RejectsBadChannelCounts) {
  EXPECT_THROW(nd::comedi::ScanDecoder(nd::comedi::SampleWidth::k16Bit, {}), std::invalid_argument);
  EXPECT_THROW(
      nd::comedi::ScanDecoder(nd::comedi::SampleWidth::k16Bit, std::vector<nd::comedi::ChannelConversion>(
                                                                   17, nd::comedi::linear_conversion(-1, 1, 65535, 1))),
      std::invalid_argument);
}

namespace {

constexpr std::size_t kChannels = 3;
constexpr std::size_t kScans = 2000;

// Random codes and the expected SI values, computed from the formulas written out here.
struct Stream {
  std::vector<std::byte> bytes;
  std::vector<double> expected;
};

std::vector<nd::comedi::ChannelConversion> three_channels() {
  const double poly[] = {-0.25, 2e-4, -1e-10};
  return {nd::comedi::linear_conversion(-10, 10, 65535, 100.0), nd::comedi::linear_conversion(0, 5, 65535, 1.0),
          nd::comedi::polynomial_conversion(poly, 2, 30000.0, 7.0)};
}

Stream make_stream(nd::comedi::SampleWidth width, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::uint32_t> code(0, 65535);
  std::vector<std::uint16_t> r16;
  std::vector<std::uint32_t> r32;
  Stream s;
  for (std::size_t i = 0; i < kScans * kChannels; ++i) {
    const std::uint32_t raw = code(rng);
    (width == nd::comedi::SampleWidth::k16Bit) ? r16.push_back(static_cast<std::uint16_t>(raw)) : r32.push_back(raw);
    const double x = raw;
    switch (i % kChannels) {
      case 0:
        s.expected.push_back(100.0 * (20.0 * (x / 65535.0) - 10.0));
        break;
      case 1:
        s.expected.push_back(5.0 * x / 65535.0);
        break;
      default: {
        const double dx = x - 30000.0;
        s.expected.push_back(7.0 * (-0.25 + 2e-4 * dx - 1e-10 * dx * dx));
      }
    }
  }
  s.bytes = width == nd::comedi::SampleWidth::k16Bit ? bytes_of(r16) : bytes_of(r32);
  return s;
}

void expect_matches(const std::vector<double>& got, const std::vector<double>& expected) {
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) ASSERT_NEAR(got[i], expected[i], 1e-9) << "sample " << i;
}

}  // namespace

class ComediScanSplits : public ::testing::TestWithParam<nd::comedi::SampleWidth> {};

TEST_P(ComediScanSplits, ArbitrarySplitsEqualOnePiece) {
  const Stream s = make_stream(GetParam(), 11);
  nd::comedi::ScanDecoder whole(GetParam(), three_channels());
  const auto one_piece = decode_all(whole, s.bytes);
  expect_matches(one_piece, s.expected);
  EXPECT_EQ(whole.pending_bytes(), 0u);

  nd::comedi::ScanDecoder bytewise(GetParam(), three_channels());
  std::vector<double> by_byte;
  for (const std::byte& b : s.bytes)
    bytewise.feed(&b, 1, [&](const double* v) { by_byte.insert(by_byte.end(), v, v + kChannels); });
  EXPECT_EQ(by_byte, one_piece);

  nd::comedi::ScanDecoder chunked(GetParam(), three_channels());
  std::vector<double> by_chunk;
  std::mt19937 rng(5);
  std::uniform_int_distribution<std::size_t> len(0, 23);
  for (std::size_t pos = 0; pos < s.bytes.size();) {
    const std::size_t n = std::min(len(rng), s.bytes.size() - pos);
    chunked.feed(s.bytes.data() + pos, n, [&](const double* v) { by_chunk.insert(by_chunk.end(), v, v + kChannels); });
    pos += n;
  }
  EXPECT_EQ(by_chunk, one_piece);
}

TEST_P(ComediScanSplits, ResetDropsPartialScan) {
  const Stream s = make_stream(GetParam(), 3);
  nd::comedi::ScanDecoder d(GetParam(), three_channels());
  std::vector<double> out;
  auto sink = [&](const double* v) { out.insert(out.end(), v, v + kChannels); };
  d.feed(s.bytes.data(), d.scan_bytes() + 3, sink);  // one scan and a fragment
  EXPECT_EQ(d.pending_bytes(), 3u);
  d.reset();
  d.feed(s.bytes.data() + d.scan_bytes(), d.scan_bytes(), sink);  // next scan, from its boundary
  ASSERT_EQ(out.size(), 2 * kChannels);
  for (std::size_t i = 0; i < out.size(); ++i) EXPECT_NEAR(out[i], s.expected[i], 1e-9);
}

TEST_P(ComediScanSplits, PipeThroughDeviceReadLoop) {
  const Stream s = make_stream(GetParam(), 17);
  int fds[2];
  ASSERT_EQ(pipe2(fds, O_CLOEXEC), 0);
  ASSERT_LT(s.bytes.size(), 60000u);  // fits the default 64 KiB pipe buffer: write all, then close
  ASSERT_EQ(write(fds[1], s.bytes.data(), s.bytes.size()), static_cast<ssize_t>(s.bytes.size()));
  close(fds[1]);

  nd::comedi::ScanDecoder d(GetParam(), three_channels());
  std::vector<double> got;
  std::array<std::byte, 13> buffer{};  // odd size: reads split samples and scans
  std::atomic<bool> stop{false};
  nd::comedi::ReadLoopConfig cfg{.device_path = "pipe", .subdevice = 2};
  int restarts = 0;
  const auto r = nd::comedi::run_read_loop(
      fds[0], buffer,
      [&](const std::byte* b, std::size_t n) {
        d.feed(b, n, [&](const double* v) { got.insert(got.end(), v, v + kChannels); });
      },
      [&] { return ++restarts, true; }, stop, cfg);
  close(fds[0]);
  EXPECT_FALSE(r.failed) << r.message;
  EXPECT_EQ(r.bytes, s.bytes.size());
  EXPECT_EQ(r.overruns, 0u);
  EXPECT_EQ(restarts, 0);
  EXPECT_NE(r.message.find("pipe subdevice 2"), std::string::npos) << r.message;
  expect_matches(got, s.expected);
}

INSTANTIATE_TEST_SUITE_P(Widths, ComediScanSplits,
                         ::testing::Values(nd::comedi::SampleWidth::k16Bit, nd::comedi::SampleWidth::k32Bit),
                         [](const auto& info) {
                           return info.param == nd::comedi::SampleWidth::k16Bit ? "16bit" : "32bit";
                         });
