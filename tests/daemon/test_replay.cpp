// noisemon replay on hand-made logs: what it refuses, what it skips and counts, and that it reports.
#include <gtest/gtest.h>

#include <cmath>
#include <lcm/lcm-cpp.hpp>
#include <numbers>

#include "daemon/replay.hpp"
#include "daemon/report_messages.hpp"

using namespace noisemon;

namespace {

template <class Message>
void write(lcm::LogFile& log, const std::string& channel, const Message& m, std::int64_t utime) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(buf.size()), buf.data()};
  log.writeEvent(&e);
}

std::string error_of(const daemon::ReplayOptions& o) {
  try {
    daemon::run_replay(o);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

drivers::StreamInfo info() {
  drivers::StreamInfo i;
  i.epoch_utime = 1'000'000;
  i.mic_count = 1;
  i.mic_positions_m = {{0, 0, 1.75}};
  i.radius_m = 1.75;
  i.acoustic_delay_s = 0.0;
  return i;
}

}  // namespace

TEST(Replay, RawBlockBeforeTheSessionIsAnErrorNamingFileAndEvent) {
  const std::string path = ::testing::TempDir() + "/nosession.lcmlog";
  {
    lcm::LogFile log(path, "w");
    drivers::SampleBlock b;
    b.first_index = 0;
    b.frames = 10;
    b.channels = 2;
    write(log, "NOISEMON_RAW", daemon::to_message(b, 0, 0), 1);
  }
  daemon::ReplayOptions o;
  o.log_path = path;
  o.progress = false;
  const std::string err = error_of(o);
  EXPECT_NE(err.find(path), std::string::npos) << err;
  EXPECT_NE(err.find("event 0"), std::string::npos) << err;
  EXPECT_NE(err.find("NOISEMON_SESSION"), std::string::npos) << err;
}

TEST(Replay, MissingFileIsAnErrorNamingIt) {
  daemon::ReplayOptions o;
  o.log_path = "/nonexistent/x.lcmlog";
  EXPECT_NE(error_of(o).find("/nonexistent/x.lcmlog: cannot open"), std::string::npos);
}

TEST(Replay, DamagedAndForeignEventsAreSkippedAndCountedAndCyclesStillCome) {
  // One microphone hearing the pressure's 1 kHz tone through nothing: 40 cycles of 1000 frames.
  const std::string path = ::testing::TempDir() + "/mixed.lcmlog";
  const int cycle = 1000, total = 40 * cycle;
  {
    lcm::LogFile log(path, "w");
    write(log, "NOISEMON_SESSION", daemon::to_message(info(), "test", 0), 0);
    std::vector<char> junk(300, 'x');
    lcm::LogEvent bad{0, 1, "NOISEMON_RAW", static_cast<std::int32_t>(junk.size()), junk.data()};
    log.writeEvent(&bad);
    lcm::LogEvent other{0, 1, "SOMEONE_ELSE", static_cast<std::int32_t>(junk.size()), junk.data()};
    log.writeEvent(&other);
    for (int first = 0; first < total; first += 200) {
      drivers::SampleBlock p, m;
      p.first_index = m.first_index = first;
      p.frames = m.frames = 200;
      p.channels = 2;
      m.channels = 1;
      for (int f = 0; f < 200; ++f) {
        const int k = first + f;
        const double x = 1e3 * std::sin(2 * std::numbers::pi * 1000.0 * k / 40000.0);
        p.data[2 * f] = 1e5 + x;
        p.data[2 * f + 1] = -360.0 + 720.0 * (k % cycle) / cycle;
        m.data[f] = 1e-3 * x;
      }
      write(log, "NOISEMON_RAW", daemon::to_message(p, 0, 1'000'000), 2);
      write(log, "NOISEMON_RAW", daemon::to_message(m, 1, 1'000'000), 2);
    }
  }
  daemon::ReplayOptions o;
  o.log_path = path;
  o.progress = false;
  const daemon::ReplaySummary s = daemon::run_replay(o);
  EXPECT_EQ(s.skipped_damaged, 1);
  EXPECT_EQ(s.skipped_unknown, 1);
  EXPECT_EQ(s.raw_blocks, 2 * total / 200);
  // Boundaries at frames 1000, 2000, ... 39000: 38 closed cycles; frames before the first warm the filters up
  // and the cycle from 39000 never closes.
  EXPECT_EQ(s.reports, 38);
  EXPECT_EQ(s.cycles_dropped, 0);
}
