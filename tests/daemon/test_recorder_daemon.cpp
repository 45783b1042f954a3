// noisemond's recorder in the real process: with [record] on and [lcm] publish_raw off, the raw streams stay off the
// bus (an LCM log URL stands for it) yet reach the file, and `noisemon replay` of the file gives the very cycle reports
// the daemon published; the status says what the recorder did; SIGINT leaves the file whole, and a daemon killed
// (SIGKILL) mid-file leaves one that replays up to its last whole event.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "drivers/formats/lcm_log_reader.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/status_t.hpp"
#include "tests/e2e/private_network.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using noisemon::test::allowance;
using noisemon::test::kNoisemon;
using noisemon::test::kNoisemond;
using noisemon::test::kStartUp;

// The sim's default speed: the engine time of n cycles, which an unpaced daemon takes less than.
std::chrono::duration<double> recd_engine_time(int cycles) {
  return std::chrono::duration<double>(cycles * 120.0 / 3050.0);
}

// Each channel's events of a log, as encoded.
std::map<std::string, std::vector<std::vector<std::uint8_t>>> recd_events(const fs::path& log,
                                                                          std::int64_t* damaged = nullptr) {
  noisemon::drivers::formats::LcmLogReader reader(log);
  noisemon::drivers::formats::LcmLogEvent e;
  std::map<std::string, std::vector<std::vector<std::uint8_t>>> out;
  while (reader.next(e)) out[std::string(e.channel)].emplace_back(e.data, e.data + e.datalen);
  if (damaged) *damaged = reader.damaged();
  return out;
}

template <class Message>
Message recd_decode(const std::vector<std::uint8_t>& bytes) {
  Message m;
  EXPECT_GE(m.decode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);
  return m;
}

// A report as encoded, less the CPU time it took (a measurement of the run, not of the engine).
std::vector<std::uint8_t> recd_without_cpu_time(const std::vector<std::uint8_t>& bytes) {
  auto m = recd_decode<noisemon::cycle_report_t>(bytes);
  m.processing_ms = 0;
  std::vector<std::uint8_t> out(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(out.data(), 0, static_cast<int>(out.size()));
  return out;
}

std::vector<fs::path> recd_files(const fs::path& dir) {
  std::vector<fs::path> files;
  if (fs::exists(dir))
    for (const auto& entry : fs::directory_iterator(dir)) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::int64_t recd_counter(const noisemon::status_t& s, const std::string& name) {
  for (int i = 0; i < s.ncounters; ++i)
    if (s.counter_name[i] == name) return s.counter_value[i];
  ADD_FAILURE() << "no counter " << name;
  return -1;
}

std::int64_t recd_overruns(const noisemon::status_t& s, const std::string& ring) {
  for (int i = 0; i < s.nrings; ++i)
    if (s.ring_name[i] == ring) return s.ring_overruns[i];
  ADD_FAILURE() << "no ring " << ring;
  return -1;
}

// A recording daemon's configuration: raw streams for the recorder alone, rings that hold seconds of data.
std::string recd_config(const std::string& dir, bool paced) {
  const std::string path = dir + "/recording.toml";
  std::ofstream(path) << (paced ? noisemon::test::sim_pacing_toml() : "[sim]\npaced = false\n")
                      << "[processing]\nring_seconds = 5.0\n[lcm]\npublish_raw = false\n"
                      << "[record]\nenabled = true\ndir = \"records\"\ntest_point = \"tp1\"\n";
  return path;
}

// The cycle reports in the recordings made so far.
std::size_t recd_reports_in(const fs::path& dir) {
  std::size_t n = 0;
  for (const fs::path& f : recd_files(dir)) n += recd_events(f)["NOISEMON_CYCLE"].size();
  return n;
}

}  // namespace

TEST(Noisemond, ARecordingWithoutRawStreamsOnTheBusReplaysToTheReportsItPublished) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string bus = dir + "/bus.lcmlog", replayed = dir + "/replayed.lcmlog";
  fs::remove_all(dir + "/records");  // a test repeated in one process starts from no recording
  constexpr int kCycles = 30;
  const pid_t daemon = noisemon::test::spawn({kNoisemond, "--config", recd_config(dir, false), "--lcm",
                                              "file://" + bus + "?mode=w", "--cycles", std::to_string(kCycles)},
                                             dir + "/daemon.out", dir + "/daemon.err");
  ASSERT_EQ(noisemon::test::wait_for(daemon, allowance(kStartUp + recd_engine_time(kCycles))), 0)
      << noisemon::test::slurp(dir + "/daemon.err");
  const std::vector<fs::path> files = recd_files(dir + "/records");
  ASSERT_EQ(files.size(), 1u);
  EXPECT_TRUE(files[0].filename().string().starts_with("tp1_")) << files[0];
  EXPECT_TRUE(files[0].filename().string().ends_with("_001.lcmlog")) << files[0];

  auto on_bus = recd_events(bus);
  std::int64_t damaged = -1;
  auto recorded = recd_events(files[0], &damaged);
  EXPECT_EQ(damaged, 0);
  EXPECT_EQ(on_bus.count("NOISEMON_RAW"), 0u) << "publish_raw = false put raw blocks on the bus";
  EXPECT_GT(recorded["NOISEMON_RAW"].size(), 100u);
  EXPECT_FALSE(on_bus["NOISEMON_SESSION"].empty());
  EXPECT_FALSE(recorded["NOISEMON_SESSION"].empty());
  ASSERT_EQ(on_bus["NOISEMON_CYCLE"].size(), static_cast<std::size_t>(kCycles));
  EXPECT_EQ(recorded.count("NOISEMON_RECORD_LOSS"), 0u);
  // Both got every other message, as published: reports, sessions, operating points, status, statistics.
  std::size_t recorded_events = 0;
  for (const auto& [channel, events] : recorded) {
    recorded_events += events.size();
    if (channel != "NOISEMON_RAW") {
      EXPECT_EQ(events, on_bus[channel]) << channel;
    }
  }
  EXPECT_EQ(recorded.size(), on_bus.size() + 1);  // the channels: the bus's and the raw streams

  // The last status: nothing lost on the way to the recorder or in it, and what it wrote.
  ASSERT_FALSE(on_bus["NOISEMON_STATUS"].empty());
  const auto status = recd_decode<noisemon::status_t>(on_bus["NOISEMON_STATUS"].back());
  EXPECT_EQ(recd_overruns(status, "raw_publish"), 0);
  EXPECT_EQ(recd_overruns(status, "record"), 0);
  EXPECT_EQ(status.record_file, files[0].string());
  EXPECT_GT(recd_counter(status, "record.bytes_written"), 0);
  // The recorder had been handed all but the last few messages when the daemon took its last status.
  EXPECT_GT(recd_counter(status, "record.messages_sent"), 0);
  EXPECT_LE(recd_counter(status, "record.messages_sent"), static_cast<std::int64_t>(recorded_events));

  const pid_t replay =
      noisemon::test::spawn({kNoisemon, "replay", files[0].string(), "--out", replayed, "--no-progress"},
                            dir + "/replay.out", dir + "/replay.err");
  ASSERT_EQ(noisemon::test::wait_for(replay, allowance(kStartUp + recd_engine_time(kCycles))), 0)
      << noisemon::test::slurp(dir + "/replay.err");
  const auto offline = recd_events(replayed)["NOISEMON_CYCLE"];
  ASSERT_GE(offline.size(), static_cast<std::size_t>(kCycles));
  for (int i = 0; i < kCycles; ++i)
    EXPECT_EQ(recd_without_cpu_time(offline[static_cast<std::size_t>(i)]),
              recd_without_cpu_time(on_bus["NOISEMON_CYCLE"][static_cast<std::size_t>(i)]))
        << "cycle " << i;
}

TEST(Noisemond, SigintClosesTheRecordingWholeAndSigkillLeavesOneThatReplaysToItsLastWholeEvent) {
  for (const int signal : {SIGINT, SIGKILL}) {
    const std::string dir = noisemon::test::unique_temp_dir() + "/" + std::to_string(signal);
    fs::remove_all(dir);
    fs::create_directories(dir);
    constexpr int kCycles = 10;
    const pid_t daemon = noisemon::test::spawn({kNoisemond, "--config", recd_config(dir, true), "--lcm", "memq://"},
                                               dir + "/daemon.out", dir + "/daemon.err");
    // The writer hands each batch to the kernel at once: the file grows while the daemon runs.
    EXPECT_TRUE(noisemon::test::wait_until([&] { return recd_reports_in(dir + "/records") >= kCycles; },
                                           allowance(kStartUp + recd_engine_time(kCycles))))
        << noisemon::test::slurp(dir + "/daemon.err");
    kill(daemon, signal);
    const int status = noisemon::test::wait_for(daemon, allowance(1s));
    EXPECT_EQ(status, signal == SIGINT ? 0 : 128 + SIGKILL) << noisemon::test::slurp(dir + "/daemon.err");
    const std::vector<fs::path> files = recd_files(dir + "/records");
    ASSERT_EQ(files.size(), 1u);
    std::int64_t damaged = -1;
    const std::size_t reports = recd_events(files[0], &damaged)["NOISEMON_CYCLE"].size();
    if (signal == SIGINT) {
      EXPECT_EQ(damaged, 0) << "SIGINT left a partial event";
    }
    EXPECT_LE(damaged, 1);  // a killed writer: at most the event it was writing, cut
    const std::string csv = dir + "/replayed.csv";
    const pid_t replay = noisemon::test::spawn({kNoisemon, "replay", files[0].string(), "--csv", csv, "--no-progress"},
                                               dir + "/replay.out", dir + "/replay.err");
    ASSERT_EQ(noisemon::test::wait_for(replay, allowance(kStartUp + recd_engine_time(static_cast<int>(reports)))), 0)
        << noisemon::test::slurp(dir + "/replay.err");
    std::ifstream in(csv);
    std::size_t rows = 0;
    for (std::string line; std::getline(in, line);) ++rows;
    // Every cycle whose blocks are in the file: the reports the daemon had published, but for the last, whose
    // blocks may not all have been written when it was killed.
    EXPECT_GE(rows - 1, reports - 1) << signal;
  }
}
