// noisemon replay on hand-made logs: what it refuses, what it skips and counts, that it reports, and that a
// second replay of the same log reports the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <numbers>
#include <sstream>
#include <vector>

#include "daemon/replay.hpp"
#include "daemon/report_messages.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "tests/drivers/unique_temp.hpp"

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
  const std::string path = noisemon::test::unique_temp_dir() + "/nosession.lcmlog";
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

namespace {

// One microphone hearing the pressure's 1 kHz tone through nothing: 40 cycles of 1000 frames, with one damaged
// and one foreign event after the session.
constexpr int kCycle = 1000, kTotal = 40 * kCycle;

void write_mixed_log(const std::string& path) {
  const int cycle = kCycle, total = kTotal;
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
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST(Replay, DamagedAndForeignEventsAreSkippedAndCountedAndCyclesStillCome) {
  const std::string path = noisemon::test::unique_temp_dir() + "/mixed.lcmlog";
  const int total = kTotal;
  write_mixed_log(path);
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

TEST(Replay, SameLogTwiceGivesIdenticalReports) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string path = dir + "/twice.lcmlog";
  write_mixed_log(path);
  std::vector<std::vector<noisemon::cycle_report_t>> reports(2);
  std::vector<std::vector<std::int64_t>> stamps(2);
  std::vector<std::string> csv(2);
  for (int run = 0; run < 2; ++run) {
    daemon::ReplayOptions o;
    o.log_path = path;
    o.progress = false;
    o.out_log = dir + "/reports" + std::to_string(run) + ".lcmlog";
    o.csv_path = dir + "/reports" + std::to_string(run) + ".csv";
    daemon::run_replay(o);
    csv[run] = read_bytes(o.csv_path);
    lcm::LogFile f(o.out_log, "r");
    while (const lcm::LogEvent* e = f.readNextEvent()) {
      noisemon::cycle_report_t m;
      ASSERT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
      m.processing_ms = 0;  // the CPU time the cycle took: a measurement of this run, not of the engine
      reports[run].push_back(m);
      stamps[run].push_back(e->timestamp);
    }
  }
  ASSERT_EQ(reports[0].size(), 38u);
  EXPECT_EQ(csv[0], csv[1]);
  EXPECT_EQ(std::count(csv[0].begin(), csv[0].end(), '\n'), 1 + 38);  // header and one row per cycle
  EXPECT_EQ(stamps[0], stamps[1]);
  ASSERT_EQ(reports[1].size(), reports[0].size());
  for (std::size_t i = 0; i < reports[0].size(); ++i) {
    // Byte for byte once encoded: every level, flag and operating-point field (NaN included).
    std::vector<char> a(static_cast<std::size_t>(reports[0][i].getEncodedSize())), b(a.size());
    reports[0][i].encode(a.data(), 0, static_cast<int>(a.size()));
    reports[1][i].encode(b.data(), 0, static_cast<int>(b.size()));
    EXPECT_EQ(a, b) << "cycle " << i;
  }
}
