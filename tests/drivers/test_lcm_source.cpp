// The lcm source decodes what it receives with the one raw-stream decoder: a microphone block whose channel count
// does not fit the session is counted as damaged and dropped (it used to reach CycleProcessor::add_mics, which
// threw and ended the processing thread), and the source keeps delivering the blocks after it. LCM's file provider
// plays a hand-made log as the network (no multicast, no root).
#include "drivers/lcm/lcm_source.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <lcm/lcm-cpp.hpp>
#include <thread>
#include <vector>

#include "drivers/formats/stream_messages.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/driver_counters.hpp"
#include "tests/support/unique_temp.hpp"

namespace nd = noisemon::drivers;

namespace {

constexpr std::int64_t kLcmSourceEpoch = 1'700'000'000'000'000;

template <class Message>
void write(lcm::LogFile& log, const std::string& channel, const Message& m, std::int64_t utime) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(buf.size()), buf.data()};
  log.writeEvent(&e);
}

// Every sample `value`; a pressure block's crank angle at 0 deg.
nd::SampleBlock block(std::int64_t first_index, std::uint32_t channels, double value, bool pressure = false) {
  nd::SampleBlock b;
  b.first_index = first_index;
  b.frames = 8;
  b.channels = channels;
  for (std::uint32_t i = 0; i < b.frames * channels; ++i)
    b.data[i] = pressure && i % 2 == nd::kCrankChannel ? 0.0 : value;
  return b;
}

using noisemon::test::counter;

std::vector<nd::SampleBlock> drain(nd::BlockRing& ring) {
  std::vector<nd::SampleBlock> out;
  nd::SampleBlock b;
  while (ring.read(&b, 1) == 1) out.push_back(b);
  return out;
}

}  // namespace

TEST(LcmSource, AMicrophoneBlockThatDoesNotFitTheSessionIsCountedNotDeliveredAndTheSourceGoesOn) {
  const std::string path = noisemon::test::unique_temp_dir() + "/bad_mic_block.lcmlog";
  {
    nd::StreamInfo info;
    info.epoch_utime = kLcmSourceEpoch;
    info.mic_count = 2;
    info.mic_positions_m = {{1, 0, 0}, {0, 1, 0}};
    lcm::LogFile log(path, "w");
    write(log, "NOISEMON_SESSION", nd::formats::to_message(info, "test", kLcmSourceEpoch), kLcmSourceEpoch);
    const auto raw = [&](const nd::SampleBlock& b, std::int8_t stream) {
      write(log, "NOISEMON_RAW", nd::formats::to_message(b, stream, kLcmSourceEpoch), kLcmSourceEpoch);
    };
    raw(block(0, 2, 1e5, true), noisemon::raw_block_t::STREAM_PRESSURE);
    raw(block(0, 2, 0.1), noisemon::raw_block_t::STREAM_MICS);
    raw(block(8, 3, 0.2), noisemon::raw_block_t::STREAM_MICS);  // three channels in a two-microphone session
    raw(block(8, 2, 1e5, true), noisemon::raw_block_t::STREAM_PRESSURE);
    raw(block(8, 2, 0.3), noisemon::raw_block_t::STREAM_MICS);
    nd::OperatingPoint op;
    op.speed_rpm = 1500;
    write(log, "NOISEMON_OP", nd::formats::to_message(op), kLcmSourceEpoch);
  }
  nd::lcm::LcmSourceConfig config;
  config.url = "file://" + path + "?speed=0";
  config.session_timeout_s = noisemon::test::allowance_s(1);
  auto source = nd::lcm::make_lcm_source(config);
  EXPECT_EQ(source->info().mic_count, 2u);
  nd::BlockRing pressure(16), mics(16);
  nd::OperatingPointRing ops(16);
  source->start({&pressure, &mics, &ops});
  // A few messages from a file.
  const auto deadline = std::chrono::steady_clock::now() + noisemon::test::allowance(std::chrono::seconds(1));
  while (ops.empty() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_FALSE(ops.empty()) << "the operating point after the bad block never arrived";
  EXPECT_EQ(source->thread_status().at(0).state, nd::ThreadState::kRunning);
  EXPECT_EQ(counter(*source, "lcm.blocks"), 4);
  EXPECT_EQ(counter(*source, "lcm.damaged_blocks"), 1);
  EXPECT_EQ(counter(*source, "lcm.other_session_blocks"), 0);
  source->stop();
  const std::vector<nd::SampleBlock> p = drain(pressure), m = drain(mics);
  ASSERT_EQ(p.size(), 2u);
  ASSERT_EQ(m.size(), 2u);
  for (const nd::SampleBlock& b : m) EXPECT_EQ(b.channels, 2u);
  EXPECT_EQ(m[0].data[0], 0.1);
  EXPECT_EQ(m[1].data[0], 0.3);
  EXPECT_EQ(m[1].first_index, 8);
}
