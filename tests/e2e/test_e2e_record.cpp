// End to end: the test bed drives noisemond's recorder over real LCM multicast in a private network namespace.
// `noisemon record start`, `mark` and `stop` each get the daemon's answer; the file holds the test point's
// recording with the session first, the three acknowledgements where they were given, and replays to the very cycle
// reports the daemon published while it ran. Without a daemon, `record` says so and exits 2.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "drivers/formats/lcm_log_reader.hpp"
#include "noisemon/command_ack_t.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "tests/e2e/private_network.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

namespace fs = std::filesystem;
using noisemon::test::allowance;
using noisemon::test::kLcmUrl;
using noisemon::test::kStartUp;
using noisemon::test::spawn;
using noisemon::test::wait_for;
using noisemon::test::wait_until;
using namespace std::chrono_literals;
const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new noisemon::test::PrivateNetwork);

struct Event {
  std::string channel;
  std::vector<std::uint8_t> data;
};

std::vector<Event> events_of(const fs::path& log) {
  noisemon::drivers::formats::LcmLogReader reader(log);
  noisemon::drivers::formats::LcmLogEvent e;
  std::vector<Event> out;
  while (reader.next(e)) out.push_back({std::string(e.channel), std::vector<std::uint8_t>(e.data, e.data + e.datalen)});
  return out;
}

template <class Message>
Message decoded(const Event& e) {
  Message m;
  EXPECT_GE(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
  return m;
}

// The cycle reports of a log by their stamps.
std::map<std::int64_t, noisemon::cycle_report_t> reports_of(const std::vector<Event>& events) {
  std::map<std::int64_t, noisemon::cycle_report_t> out;
  for (const Event& e : events)
    if (e.channel == "NOISEMON_CYCLE") {
      const auto m = decoded<noisemon::cycle_report_t>(e);
      out[m.utime] = m;
    }
  return out;
}

// `noisemon record ARGS...` on the test's bus: its exit status and what it printed.
struct Answer {
  int status = -1;
  std::string out;
};
Answer record(const std::string& dir, const std::vector<std::string>& args, const std::string& name) {
  std::vector<std::string> argv{NOISEMON_PATH, "record"};
  argv.insert(argv.end(), args.begin(), args.end());
  argv.insert(argv.end(), {"--lcm", kLcmUrl, "--timeout", std::to_string(noisemon::test::allowance_s(5.0))});
  const pid_t p = spawn(argv, dir + "/" + name + ".out", dir + "/" + name + ".err");
  Answer a;
  a.status = wait_for(p, allowance(10s));
  a.out = noisemon::test::slurp(dir + "/" + name + ".out") + noisemon::test::slurp(dir + "/" + name + ".err");
  return a;
}

std::size_t reports_in(const fs::path& dir) {
  std::size_t n = 0;
  if (fs::exists(dir))
    for (const auto& f : fs::directory_iterator(dir)) n += reports_of(events_of(f.path())).size();
  return n;
}

}  // namespace

TEST(RecordCommand, StartMarkStopOverTheBusMakeATestPointsRecordingThatReplaysToTheLiveReports) {
  NOISEMON_REQUIRE_NAMESPACE();
  const std::string dir = noisemon::test::unique_temp_dir();
  fs::remove_all(dir + "/records");
  const std::string config = dir + "/cell.toml";
  std::ofstream(config) << noisemon::test::sim_pacing_toml() << "[lcm]\npublish_raw = false\n"
                        << "[record]\nenabled = true\nautostart = false\ndir = \"records\"\n";
  const pid_t daemon =
      spawn({NOISEMOND_PATH, "--config", config, "--lcm", kLcmUrl}, dir + "/daemon.out", dir + "/daemon.err");
  const Answer start = record(dir, {"start", "idle-1800"}, "start");
  ASSERT_EQ(start.status, 0) << start.out << noisemon::test::slurp(dir + "/daemon.err");
  EXPECT_NE(start.out.find("recording test point idle-1800"), std::string::npos) << start.out;
  EXPECT_TRUE(wait_until([&] { return reports_in(dir + "/records") >= 40; }, allowance(kStartUp + 4s)));
  const Answer mark = record(dir, {"mark", "door opened"}, "mark");
  EXPECT_EQ(mark.status, 0) << mark.out;
  EXPECT_TRUE(wait_until([&] { return reports_in(dir + "/records") >= 80; }, allowance(4s)));
  const Answer stop = record(dir, {"stop"}, "stop");
  EXPECT_EQ(stop.status, 0) << stop.out;
  kill(daemon, SIGTERM);
  EXPECT_EQ(wait_for(daemon, allowance(5s)), 0) << noisemon::test::slurp(dir + "/daemon.err");

  std::vector<fs::path> files;
  for (const auto& f : fs::directory_iterator(dir + "/records")) files.push_back(f.path());
  ASSERT_EQ(files.size(), 1u);
  EXPECT_TRUE(files[0].filename().string().starts_with("idle-1800_")) << files[0];
  EXPECT_NE(stop.out.find(files[0].string()), std::string::npos) << stop.out;
  const std::vector<Event> recorded = events_of(files[0]);
  ASSERT_FALSE(recorded.empty());
  EXPECT_EQ(recorded[0].channel, "NOISEMON_SESSION");  // kept from before the start: the file replays on its own
  std::vector<std::string> acks;
  for (const Event& e : recorded)
    if (e.channel == "NOISEMON_CMD_ACK") acks.push_back(decoded<noisemon::command_ack_t>(e).verb);
  EXPECT_EQ(acks, (std::vector<std::string>{"record_start", "mark", "record_stop"}));
  EXPECT_EQ(recorded.back().channel, "NOISEMON_CMD_ACK");

  // The replay of the file, which starts in the middle of a run: its filters and model start from rest, so its first
  // cycles are flagged settling; after them each cycle is the one the daemon published: the figures of the pressure
  // to the last digit, the levels to 0.05 dB (the filters' start decays away, not to the last bit).
  const std::string replayed = dir + "/replayed.lcmlog";
  const pid_t replay = spawn({NOISEMON_PATH, "replay", files[0].string(), "--out", replayed, "--no-progress"},
                             dir + "/replay.out", dir + "/replay.err");
  ASSERT_EQ(wait_for(replay, allowance(kStartUp + 10s)), 0) << noisemon::test::slurp(dir + "/replay.err");
  const auto live = reports_of(recorded), offline = reports_of(events_of(replayed));
  std::size_t settled = 0;
  for (const auto& [utime, r] : offline) {
    ASSERT_EQ(live.count(utime), 1u) << "a replayed cycle the daemon did not publish while recording: " << utime;
    const noisemon::cycle_report_t& l = live.at(utime);
    EXPECT_EQ(r.imep_net_bar, l.imep_net_bar) << utime;
    EXPECT_EQ(r.peak_pressure_bar, l.peak_pressure_bar) << utime;
    if (r.flags & noisemon::cycle_report_t::CYCLE_SETTLING) {
      EXPECT_EQ(settled, 0u) << "a settling cycle after settled ones: " << utime;
      continue;
    }
    ++settled;
    EXPECT_EQ(r.flags, l.flags) << utime;
    EXPECT_NEAR(r.lpa_measured_db, l.lpa_measured_db, 0.05) << utime;
    EXPECT_NEAR(r.lpa_predicted_db, l.lpa_predicted_db, 0.05) << utime;
    EXPECT_NEAR(r.lwa_measured_db, l.lwa_measured_db, 0.05) << utime;
  }
  std::printf("%zu cycles recorded, %zu replayed, %zu of them settled\n", live.size(), offline.size(), settled);
  EXPECT_GE(settled, 10u) << offline.size() << " replayed of " << live.size() << " recorded";
}

TEST(RecordCommand, WithoutADaemonTheAnswerSaysSoAndTheExitStatusIs2) {
  NOISEMON_REQUIRE_NAMESPACE();
  const std::string dir = noisemon::test::unique_temp_dir();
  const pid_t p =
      spawn({NOISEMON_PATH, "record", "stop", "--lcm", kLcmUrl, "--timeout", "1"}, dir + "/out", dir + "/err");
  EXPECT_EQ(wait_for(p, allowance(10s)), 2);
  EXPECT_NE(noisemon::test::slurp(dir + "/err").find("no noisemond answered on NOISEMON_CMD"), std::string::npos)
      << noisemon::test::slurp(dir + "/err");
}
