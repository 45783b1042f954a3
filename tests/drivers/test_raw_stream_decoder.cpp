// The one decoder of the raw stream: sessions start, repeat and change by the one rule (epoch, microphone count,
// condition); a block comes out with the samples that went in; every kind of damage is refused with its reason,
// and the kind tells a reader whether to count it as damage or as another run's block.
#include "drivers/formats/raw_stream_decoder.hpp"
#include "noisemon/session_v1_t.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "drivers/formats/stream_messages.hpp"

namespace noisemon::drivers {
namespace {

constexpr std::int64_t kDecoderEpoch = 1'700'000'000'000'000;

template <class Message>
std::vector<std::uint8_t> bytes_of(const Message& m) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(b.data(), 0, static_cast<int>(b.size())), static_cast<int>(b.size()));
  return b;
}

StreamInfo two_mics(std::int64_t epoch = kDecoderEpoch) {
  StreamInfo i;
  i.epoch_utime = epoch;
  i.mic_count = 2;
  i.mic_positions_m = {{1, 0, 0}, {0, 1, 0}};
  i.radius_m = 1.75;
  return i;
}

// A pressure block of `frames` frames at first_index, crank inside [-360, 360).
noisemon::raw_block_t pressure_block(std::int64_t first_index = 256, std::uint32_t frames = 4,
                                     std::int64_t epoch = kDecoderEpoch) {
  SampleBlock b;
  b.first_index = first_index;
  b.frames = frames;
  b.channels = kPressureStreamChannels;
  for (std::uint32_t f = 0; f < frames; ++f) {
    b.data[2 * f + kPressureChannel] = 1e5 + 100.0 * f;
    b.data[2 * f + kCrankChannel] = -300.0 + 0.25 * f;
  }
  return formats::to_message(b, noisemon::raw_block_t::STREAM_PRESSURE, epoch);
}

noisemon::raw_block_t mic_block(std::uint32_t channels) {
  SampleBlock b;
  b.first_index = 0;
  b.frames = 3;
  b.channels = channels;
  for (std::uint32_t i = 0; i < b.frames * channels; ++i) b.data[i] = 0.01 * i;
  return formats::to_message(b, noisemon::raw_block_t::STREAM_MICS, kDecoderEpoch);
}

class Decoder : public ::testing::Test {
 protected:
  template <class Message>
  const formats::RawEvent& feed(const std::string& channel, const Message& m) {
    const std::vector<std::uint8_t> b = bytes_of(m);
    return decoder.decode(channel, b.data(), b.size());
  }
  const formats::RawEvent& session(const StreamInfo& info, const std::string& condition = "run") {
    return feed("NOISEMON_SESSION", formats::to_message(info, "test", info.epoch_utime, condition));
  }
  // A block after the session: its event kind and reason.
  std::pair<formats::RawEventKind, std::string> block_after_session(const noisemon::raw_block_t& m) {
    session(two_mics());
    const formats::RawEvent& e = feed("NOISEMON_RAW", m);
    return {e.kind, e.reason};
  }
  formats::RawStreamDecoder decoder;
};

TEST_F(Decoder, TheFirstSessionStartsRepeatsDoNotAnotherRunDoes) {
  EXPECT_FALSE(decoder.has_session());
  EXPECT_TRUE(session(two_mics()).session_started);
  EXPECT_TRUE(decoder.has_session());
  EXPECT_EQ(decoder.info().mic_count, 2u);
  EXPECT_EQ(decoder.condition(), "run");
  EXPECT_EQ(decoder.source(), "test");
  const formats::RawEvent& repeat = session(two_mics());
  EXPECT_EQ(repeat.kind, formats::RawEventKind::kSession);
  EXPECT_FALSE(repeat.session_started);
  EXPECT_TRUE(session(two_mics(), "another condition").session_started);
  EXPECT_EQ(decoder.condition(), "another condition");
  EXPECT_TRUE(session(two_mics(kDecoderEpoch + 60'000'000), "another condition").session_started);
  EXPECT_EQ(decoder.info().epoch_utime, kDecoderEpoch + 60'000'000);
  StreamInfo one = two_mics(kDecoderEpoch + 60'000'000);
  one.mic_count = 1;
  one.mic_positions_m.resize(1);
  EXPECT_TRUE(session(one, "another condition").session_started);
}

TEST_F(Decoder, KeepFirstHoldsTheFirstSessionAndCallsLaterRunsBlocksOtherSession) {
  decoder = formats::RawStreamDecoder({formats::StreamChannels{}, formats::SessionChanges::kKeepFirst});
  ASSERT_TRUE(session(two_mics()).session_started);
  const formats::RawEvent& later = session(two_mics(kDecoderEpoch + 60'000'000), "next run");
  EXPECT_EQ(later.kind, formats::RawEventKind::kSession);
  EXPECT_FALSE(later.session_started);
  EXPECT_EQ(decoder.info().epoch_utime, kDecoderEpoch);
  EXPECT_EQ(decoder.condition(), "run");
  const formats::RawEvent& e = feed("NOISEMON_RAW", pressure_block(0, 4, kDecoderEpoch + 60'000'000));
  EXPECT_EQ(e.kind, formats::RawEventKind::kOtherSessionBlock);
  EXPECT_NE(e.reason.find("another session"), std::string::npos) << e.reason;
  EXPECT_EQ(feed("NOISEMON_RAW", pressure_block()).kind, formats::RawEventKind::kBlock);
}

TEST_F(Decoder, ABlockOfTheSessionComesOutWithItsSamples) {
  session(two_mics());
  const formats::RawEvent& e = feed("NOISEMON_RAW", pressure_block(512, 5));
  ASSERT_EQ(e.kind, formats::RawEventKind::kBlock);
  EXPECT_EQ(e.channel, formats::RawChannel::kRaw);
  EXPECT_EQ(int{e.stream}, int{noisemon::raw_block_t::STREAM_PRESSURE});
  EXPECT_EQ(e.block.first_index, 512);
  EXPECT_EQ(e.block.frames, 5u);
  EXPECT_EQ(e.block.channels, 2u);
  for (std::uint32_t f = 0; f < 5; ++f) {
    EXPECT_EQ(e.block.data[2 * f], 1e5 + 100.0 * f);
    EXPECT_EQ(e.block.data[2 * f + 1], -300.0 + 0.25 * f);
  }
  const formats::RawEvent& m = feed("NOISEMON_RAW", mic_block(2));
  ASSERT_EQ(m.kind, formats::RawEventKind::kBlock);
  EXPECT_EQ(int{m.stream}, int{noisemon::raw_block_t::STREAM_MICS});
  EXPECT_EQ(m.block.data[5], 0.05);
}

TEST_F(Decoder, OperatingPointsBelongToASession) {
  OperatingPoint op;
  op.utime = kDecoderEpoch;
  op.speed_rpm = 3050;
  op.load_nm = 12;
  EXPECT_EQ(feed("NOISEMON_OP", formats::to_message(op)).kind, formats::RawEventKind::kBeforeSession);
  EXPECT_EQ(feed("NOISEMON_RAW", pressure_block()).kind, formats::RawEventKind::kBeforeSession);
  session(two_mics());
  const formats::RawEvent& e = feed("NOISEMON_OP", formats::to_message(op));
  ASSERT_EQ(e.kind, formats::RawEventKind::kOperatingPoint);
  EXPECT_EQ(e.operating_point.speed_rpm, 3050);
  EXPECT_EQ(e.operating_point.load_nm, 12);
}

TEST_F(Decoder, PayloadsThatDoNotDecodeAreDamagedNamingTheirType) {
  const std::vector<std::uint8_t> junk(300, 'x');
  session(two_mics());
  for (const auto& [channel, type] :
       {std::pair{"NOISEMON_SESSION", "noisemon.session_t"}, std::pair{"NOISEMON_RAW", "noisemon.raw_block_t"},
        std::pair{"NOISEMON_OP", "noisemon.operating_point_t"}}) {
    const formats::RawEvent& e = decoder.decode(channel, junk.data(), junk.size());
    EXPECT_EQ(e.kind, formats::RawEventKind::kDamaged) << channel;
    EXPECT_EQ(e.reason, std::string("does not decode as ") + type);
  }
  // An operating point on the raw channel: a foreign type there.
  EXPECT_EQ(feed("NOISEMON_RAW", formats::to_message(OperatingPoint{})).reason,
            "does not decode as noisemon.raw_block_t");
  EXPECT_EQ(decoder.decode("SOMEONE_ELSE", junk.data(), junk.size()).kind, formats::RawEventKind::kOtherChannel);
}

TEST_F(Decoder, ASessionThatIsNoneIsDamagedWithTheReason) {
  noisemon::session_t m = formats::to_message(two_mics(), "test", kDecoderEpoch, "run");
  m.sample_rate_hz = 48000;
  const formats::RawEvent& e = feed("NOISEMON_SESSION", m);
  EXPECT_EQ(e.kind, formats::RawEventKind::kDamaged);
  EXPECT_NE(e.reason.find("sample rate"), std::string::npos) << e.reason;
  EXPECT_FALSE(decoder.has_session());
}

TEST_F(Decoder, EachBlockThatContradictsItsSessionOrItselfGivesItsReason) {
  EXPECT_EQ(block_after_session(mic_block(3)),
            std::pair(formats::RawEventKind::kBadBlock, std::string("microphone block with 3 channels, expected 2")));
  noisemon::raw_block_t m = pressure_block();
  m.sample_rate_hz = 48000;
  EXPECT_EQ(block_after_session(m).second, "sample rate 48000.000000 Hz, expected 40000");
  m = pressure_block();
  m.utime += 1;
  EXPECT_EQ(block_after_session(m).second, "utime does not match first_index (a damaged field)");
  m = pressure_block();
  m.stream = 7;
  EXPECT_EQ(block_after_session(m).second, "unknown stream 7");
  m = pressure_block();
  m.data[0] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(block_after_session(m).second, "infinite sample");
  m = pressure_block();
  m.data[1] = 361.0;
  EXPECT_EQ(block_after_session(m).second, "crank angle outside [-360, 360] deg");
  m = pressure_block();
  m.channels = 3;  // nsamples no longer frames x channels
  EXPECT_EQ(block_after_session(m), std::pair(formats::RawEventKind::kBadBlock,
                                              std::string("block of 4 frames x 3 channels holding 8 samples")));
}

TEST_F(Decoder, NaNSamplesPassAsDeliveredAndAreDamageForRecordings) {
  noisemon::raw_block_t m = pressure_block();
  m.data[2] = std::numeric_limits<double>::quiet_NaN();  // a faulty pressure sample, as the device delivered it
  EXPECT_EQ(block_after_session(m).first, formats::RawEventKind::kBlock);
  decoder = formats::RawStreamDecoder(
      {formats::StreamChannels{}, formats::SessionChanges::kFollow, formats::BlockCheck::kFinite});
  EXPECT_EQ(block_after_session(m), std::pair(formats::RawEventKind::kBadBlock, std::string("non-finite sample")));
}

TEST_F(Decoder, ChannelNamesAreTheConfiguredOnes) {
  decoder = formats::RawStreamDecoder(formats::RawStreamDecoderOptions{{"R", "O", "S"}});
  EXPECT_EQ(feed("NOISEMON_SESSION", formats::to_message(two_mics(), "test", kDecoderEpoch)).kind,
            formats::RawEventKind::kOtherChannel);
  EXPECT_TRUE(feed("S", formats::to_message(two_mics(), "test", kDecoderEpoch)).session_started);
  EXPECT_EQ(feed("R", pressure_block()).kind, formats::RawEventKind::kBlock);
}

// The crank-angle stream: a session whose encoder has a step of 0.01 ... 6 deg may carry it (two channels an edge,
// at most a 90 deg block); another session may not, and a block that breaks those bounds gives its reason.
TEST_F(Decoder, CrankAngleBlocksBelongToAnEncodersSessionAndKeepToTheirBounds) {
  const auto angle_block = [](std::uint32_t edges, double first_angle) {
    SampleBlock b;
    b.first_index = 512;
    b.frames = edges;
    b.channels = kAngleStreamChannels;
    for (std::uint32_t f = 0; f < edges; ++f) {
      b.data[2 * f + kAngleCrankChannel] = first_angle + 0.5 * f;
      b.data[2 * f + kAnglePressureChannel] = 1e5;
    }
    return formats::to_message(b, noisemon::raw_block_t::STREAM_PRESSURE_ANGLE, kDecoderEpoch);
  };
  StreamInfo info = two_mics();
  info.pressure_edges_per_rev = 720;  // 0.5 deg: 180 edges make 90 deg
  session(info);
  EXPECT_EQ(decoder.info().pressure_angle_step_deg, 0.5);
  const formats::RawEvent& ok = feed("NOISEMON_RAW", angle_block(180, -100.0));
  EXPECT_EQ(ok.kind, formats::RawEventKind::kBlock) << ok.reason;
  EXPECT_EQ(int{ok.stream}, int{noisemon::raw_block_t::STREAM_PRESSURE_ANGLE});
  EXPECT_EQ(ok.block.frames, 180u);
  const formats::RawEvent& wide = feed("NOISEMON_RAW", angle_block(181, -100.0));
  EXPECT_EQ(wide.kind, formats::RawEventKind::kBadBlock);
  EXPECT_NE(wide.reason.find("181 edges"), std::string::npos) << wide.reason;
  const formats::RawEvent& outside = feed("NOISEMON_RAW", angle_block(10, 356.0));
  EXPECT_EQ(outside.kind, formats::RawEventKind::kBadBlock);
  EXPECT_NE(outside.reason.find("outside [-360, 360]"), std::string::npos) << outside.reason;

  formats::RawStreamDecoder timed;  // a session sampled in time (no encoder edges): no crank-angle stream
  const std::vector<std::uint8_t> s = bytes_of(formats::to_message(two_mics(), "test", kDecoderEpoch, "run"));
  timed.decode("NOISEMON_SESSION", s.data(), s.size());
  const std::vector<std::uint8_t> b = bytes_of(angle_block(10, 0.0));
  const formats::RawEvent& refused = timed.decode("NOISEMON_RAW", b.data(), b.size());
  EXPECT_EQ(refused.kind, formats::RawEventKind::kBadBlock);
  EXPECT_NE(refused.reason.find("no crank-angle stream"), std::string::npos) << refused.reason;
}

// A log recorded before session_t had tdc_deg holds session_v1_t payloads (the same fingerprint): they decode, with
// tdc_deg 0; today's carry it; an impossible one is damage that names it.
TEST_F(Decoder, SessionsFromBeforeTdcDegDecodeWithItZero) {
  StreamInfo info = two_mics();
  info.tdc_deg = -1.84;
  const noisemon::session_t now = formats::to_message(info, "test", info.epoch_utime, "run");
  noisemon::session_v1_t old;
  old.utime = now.utime, old.epoch_utime = now.epoch_utime, old.source = now.source,
  old.sample_rate_hz = now.sample_rate_hz;
  old.radius_m = now.radius_m, old.acoustic_delay_s = now.acoustic_delay_s, old.nmics = now.nmics;
  old.mic_positions_m = now.mic_positions_m, old.condition = now.condition;
  old.pressure_full_scale_pa = now.pressure_full_scale_pa, old.mic_full_scale_pa = now.mic_full_scale_pa;
  old.pressure_edges_per_rev = now.pressure_edges_per_rev, old.mic_passband_hz = now.mic_passband_hz;
  const formats::RawEvent& e = feed("NOISEMON_SESSION", old);
  ASSERT_EQ(e.kind, formats::RawEventKind::kSession) << e.reason;
  EXPECT_EQ(decoder.info().tdc_deg, 0.0);
  EXPECT_EQ(decoder.info().mic_positions_m, info.mic_positions_m);
  formats::RawStreamDecoder fresh;
  const std::vector<std::uint8_t> b = bytes_of(now);
  ASSERT_EQ(fresh.decode("NOISEMON_SESSION", b.data(), b.size()).kind, formats::RawEventKind::kSession);
  EXPECT_EQ(fresh.info().tdc_deg, -1.84);
  noisemon::session_t wild = now;
  wild.tdc_deg = 45.0;
  const std::vector<std::uint8_t> w = bytes_of(wild);
  formats::RawStreamDecoder third;
  const formats::RawEvent& bad = third.decode("NOISEMON_SESSION", w.data(), w.size());
  EXPECT_EQ(bad.kind, formats::RawEventKind::kDamaged);
  EXPECT_NE(bad.reason.find("firing TDC at 45"), std::string::npos) << bad.reason;
}

}  // namespace
}  // namespace noisemon::drivers
