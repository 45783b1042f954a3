// The stream messages from damaged bytes, on the inputs the replay fuzzer crashed on: decode_message must refuse
// a raw block whose sample count is negative or far larger than its payload and a session whose string length or
// microphone count is damaged, without an exception and without a large allocation (intact messages decode as
// encoded); from_message must refuse a session whose acoustic delay is no frame offset (1e20 s overflowed the
// processor's frame arithmetic).
#include "drivers/formats/stream_messages.hpp"
#include "tests/support/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <new>
#include <vector>

namespace noisemon::drivers {
namespace {

template <class Message>
std::vector<std::uint8_t> encode(const Message& m) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}

void put_be32(std::vector<std::uint8_t>& b, std::size_t at, std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  for (int i = 0; i < 4; ++i) b.at(at + i) = static_cast<std::uint8_t>(u >> (24 - 8 * i));
}

noisemon::raw_block_t raw_block() {
  noisemon::raw_block_t m{};
  m.utime = 1'700'000'000'000'000;
  m.epoch_utime = m.utime;
  m.first_index = 0;
  m.stream = noisemon::raw_block_t::STREAM_PRESSURE;
  m.sample_rate_hz = 40000;
  m.channels = 2;
  m.frames = 3;
  m.nsamples = 6;
  m.data = {1e5, -360, 1.1e5, -359.9, 1.2e5, -359.8};
  return m;
}

noisemon::session_t session() {
  noisemon::session_t m{};
  m.utime = 5;
  m.epoch_utime = 7;
  m.source = "sim";
  m.sample_rate_hz = 40000;
  m.radius_m = 1.75;
  m.acoustic_delay_s = 0.005;
  m.nmics = 2;
  m.mic_positions_m = {{1, 2, 3}, {4, 5, 6}};
  m.condition = "idle";
  return m;
}

// Byte offset of raw_block_t.nsamples: just before its doubles, which end the message.
std::size_t nsamples_offset(const noisemon::raw_block_t& m) {
  return static_cast<std::size_t>(m.getEncodedSize()) - 8 * m.data.size() - 4;
}

TEST(StreamMessagesDamaged, IntactMessagesDecodeAsEncoded) {
  const auto rb = raw_block();
  const auto b = encode(rb);
  noisemon::raw_block_t r;
  ASSERT_TRUE(formats::decode_message(b.data(), b.size(), r));
  EXPECT_EQ(r.nsamples, 6);
  EXPECT_EQ(r.data, rb.data);
  EXPECT_EQ(r.frames, 3);

  const auto s = encode(session());
  noisemon::session_t sm;
  ASSERT_TRUE(formats::decode_message(s.data(), s.size(), sm));
  EXPECT_EQ(sm.source, "sim");
  EXPECT_EQ(sm.condition, "idle");
  EXPECT_EQ(sm.mic_positions_m[1][2], 6.0);

  noisemon::operating_point_t op{};
  op.speed_rpm = 1800;
  const auto o = encode(op);
  noisemon::operating_point_t om;
  ASSERT_TRUE(formats::decode_message(o.data(), o.size(), om));
  EXPECT_EQ(om.speed_rpm, 1800);
}

TEST(StreamMessagesDamaged, RawBlockClaimingTwoBillionSamplesIsRefusedWithoutAllocatingThem) {
  const auto rb = raw_block();
  for (std::int32_t claimed : {INT32_MAX, 1'000'000, 7}) {
    auto b = encode(rb);
    put_be32(b, nsamples_offset(rb), claimed);
    noisemon::test::reset_allocation_counts();
    noisemon::raw_block_t r;
    EXPECT_FALSE(formats::decode_message(b.data(), b.size(), r)) << claimed;
    EXPECT_LT(noisemon::test::largest_allocation_since_reset(), 4096U) << claimed;
  }
}

TEST(StreamMessagesDamaged, RawBlockWithNegativeSampleCountIsRefused) {
  const auto rb = raw_block();
  auto b = encode(rb);
  put_be32(b, nsamples_offset(rb), -3);
  noisemon::raw_block_t r;
  EXPECT_FALSE(formats::decode_message(b.data(), b.size(), r));
}

TEST(StreamMessagesDamaged, SessionWithDamagedStringLengthOrMicCountIsRefused) {
  // session_t: fingerprint, utime, epoch_utime (8 bytes each), then the source string's int32 length.
  const std::size_t source_len_at = 24;
  for (std::int32_t len : {0, -1, INT32_MIN, 1'000'000}) {
    auto b = encode(session());
    put_be32(b, source_len_at, len);
    noisemon::session_t m;
    EXPECT_FALSE(formats::decode_message(b.data(), b.size(), m)) << len;
  }
  // nmics (int16) follows the source ("sim" + NUL) and three doubles.
  const std::size_t nmics_at = source_len_at + 4 + 4 + 3 * 8;
  auto b = encode(session());
  ASSERT_EQ(b.at(nmics_at + 1), 2);  // the layout is the one assumed here
  b.at(nmics_at) = 0xFF;
  b.at(nmics_at + 1) = 0xFF;  // -1
  noisemon::session_t m;
  EXPECT_FALSE(formats::decode_message(b.data(), b.size(), m));
}

TEST(StreamMessagesDamaged, TruncatedPaddedOrForeignPayloadsAreRefused) {
  const auto b = encode(raw_block());
  noisemon::raw_block_t r;
  for (std::size_t n = 0; n < b.size(); ++n)
    EXPECT_FALSE(formats::decode_message(b.data(), n, r)) << "truncated to " << n;
  auto padded = b;
  padded.push_back(0);
  EXPECT_FALSE(formats::decode_message(padded.data(), padded.size(), r));
  // A session's bytes are not a raw block (fingerprint), nor the other way round.
  const auto s = encode(session());
  EXPECT_FALSE(formats::decode_message(s.data(), s.size(), r));
  noisemon::session_t sm;
  EXPECT_FALSE(formats::decode_message(b.data(), b.size(), sm));
  EXPECT_FALSE(formats::decode_message(nullptr, 10, sm));
}

TEST(StreamMessagesDamaged, SessionCarriesTheConvertersFullScalesAndRefusesImpossibleOnes) {
  StreamInfo info;
  info.mic_count = 1;
  info.mic_positions_m = {{1, 2, 3}};
  info.pressure_full_scale_pa = 250e5;
  info.mic_full_scale_pa = 3162.3;
  const auto bytes = encode(formats::to_message(info, "sim", 5));
  noisemon::session_t m;
  ASSERT_TRUE(formats::decode_message(bytes.data(), bytes.size(), m));
  EXPECT_EQ(m.pressure_full_scale_pa, 250e5);
  EXPECT_EQ(m.mic_full_scale_pa, 3162.3);
  const StreamInfo back = formats::from_message(m);
  EXPECT_EQ(back.pressure_full_scale_pa, 250e5);
  EXPECT_EQ(back.mic_full_scale_pa, 3162.3);
  // 0: not known (a session that does not say); the default.
  EXPECT_EQ(formats::from_message(session()).mic_full_scale_pa, 0.0);
  for (double fs : {-1.0, std::numeric_limits<double>::infinity(), std::nan("")}) {
    noisemon::session_t bad = session();
    bad.mic_full_scale_pa = fs;
    EXPECT_THROW(formats::from_message(bad), std::invalid_argument) << fs;
    bad = session();
    bad.pressure_full_scale_pa = fs;
    EXPECT_THROW(formats::from_message(bad), std::invalid_argument) << fs;
  }
}

TEST(StreamMessagesDamaged, SessionWithAcousticDelayOf1e20sIsRefused) {
  for (double delay : {1e20, 1.5, -0.001, std::numeric_limits<double>::infinity(), std::nan("")}) {
    noisemon::session_t m = session();
    m.acoustic_delay_s = delay;
    EXPECT_THROW(formats::from_message(m), std::invalid_argument) << delay;
  }
  noisemon::session_t ok = session();
  ok.acoustic_delay_s = 0.0051;  // 1.75 m at 343 m/s
  EXPECT_DOUBLE_EQ(formats::from_message(ok).acoustic_delay_s, 0.0051);
}

}  // namespace
}  // namespace noisemon::drivers
