// End to end: noisemond runs on the simulated engine in a private network namespace and publishes over real
// LCM multicast; a separate `noisemon watch` process receives the cycle reports and writes them to CSV.
#include <gtest/gtest.h>
#include <sched.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "drivers/formats/lcm_log_reader.hpp"
#include "drivers/formats/stream_messages.hpp"
#include "drivers/lcm/lcm_source.hpp"
#include "dsp/levels.hpp"
#include "dsp/third_octave_bank.hpp"
#include "dsp/weighting.hpp"
#include "model/block_model.hpp"
#include "model/engine/engine_cycle.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/raw_block_t.hpp"
#include "tests/e2e/private_network.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using noisemon::test::allowance;
using noisemon::test::allowance_s;
using noisemon::test::kLcmUrl;
using noisemon::test::kStartUp;
using noisemon::test::spawn;
using noisemon::test::wait_for;
using noisemon::test::wait_until;
using namespace std::chrono_literals;
const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new noisemon::test::PrivateNetwork);

// The work each wait below stands for, in the normal build on an idle machine (tests/sanitizer.hpp stretches it).
constexpr double kCyclesPerSecond = 3050.0 / 120.0;  // the sim's default speed
constexpr auto kSubscribed = 75ms;                   // a subscriber's start, up to its subscription
std::chrono::duration<double> engine_time(int cycles) {
  return std::chrono::duration<double>(cycles / kCyclesPerSecond);
}
// The time a log's events span, as the recorder stamped them: what lcm-logplayer takes to play it at speed 1.
std::chrono::duration<double> log_span(const std::string& path) {
  noisemon::drivers::formats::LcmLogReader reader{std::filesystem::path(path)};
  noisemon::drivers::formats::LcmLogEvent e;
  std::int64_t first = -1, last = 0;
  while (reader.next(e)) {
    if (first < 0) first = e.timestamp;
    last = e.timestamp;
  }
  return std::chrono::duration<double>(first < 0 ? 0.0 : 1e-6 * static_cast<double>(last - first));
}
// watch's --timeout: the longest silence it may wait through (the daemon's start-up) before it calls it an error.
const std::string kWatchTimeout = std::to_string(allowance_s(kStartUp.count()));

struct Row {
  long long cycle;
  double speed, soi, lpa_meas, lpa_pred, lwa_meas, lwa_pred;
  int flags;
};

// The rows written so far (a subscriber may be writing the file: a last line without its newline is not yet a row).
std::vector<Row> read_csv(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  std::vector<Row> rows;
  while (std::getline(in, line) && !in.eof()) {
    std::stringstream s(line);
    std::string f[12];
    for (auto& x : f) std::getline(s, x, ',');
    rows.push_back({std::stoll(f[0]), std::stod(f[2]), std::stod(f[4]), std::stod(f[6]), std::stod(f[7]),
                    std::stod(f[8]), std::stod(f[9]), std::stoi(f[11])});
  }
  return rows;
}

// A CSV's whole lines by the instant each cycle stands for (its utime, the second field; a line still being written
// is not one yet). That instant, from the streams' own frame numbers, is a cycle's identity in a recording; its number
// (the first field) counts the cycles a run completed, so after a cycle whose data a recording lost, a replay numbers
// the same cycles differently.
std::map<long long, std::string> csv_lines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // header
  std::map<long long, std::string> lines;
  while (std::getline(in, line) && !in.eof()) lines[std::stoll(line.substr(line.find(',') + 1))] = line;
  return lines;
}

// A CSV line less its cycle number: what a replay must reproduce.
std::string without_cycle_number(const std::string& line) { return line.substr(line.find(',') + 1); }

// The flags column of a CSV line (cycle_csv_header: the twelfth).
int flags_of(const std::string& line) {
  std::stringstream s(line);
  std::string field;
  for (int i = 0; i < 12; ++i) std::getline(s, field, ',');
  return std::stoi(field);
}

// The raw blocks a recording misses. The 40 kHz streams number every frame, so a block that does not start where
// the one before it ended follows a loss; the crank-angle stream has a frame per encoder edge, so a block whose first
// angle is not one step past the last one's follows a loss (a step is the angle between a block's first two edges).
int lost_raw_blocks(const std::string& log) {
  noisemon::drivers::formats::LcmLogReader reader{std::filesystem::path(log)};
  noisemon::drivers::formats::LcmLogEvent e;
  std::map<int, std::int64_t> next_index;
  std::map<int, double> next_angle;
  int lost = 0;
  while (reader.next(e)) {
    if (e.channel != "NOISEMON_RAW") continue;
    noisemon::raw_block_t b;
    if (b.decode(e.data, 0, e.datalen) < 0) {
      ++lost;
      continue;
    }
    if (b.stream != noisemon::raw_block_t::STREAM_PRESSURE_ANGLE) {
      if (next_index.count(b.stream) > 0 && b.first_index != next_index[b.stream]) ++lost;
      next_index[b.stream] = b.first_index + b.frames;
    } else if (b.frames >= 2) {
      const double step = b.data[b.channels] - b.data[0];
      if (next_angle.count(b.stream) > 0 &&
          std::abs(std::remainder(b.data[0] - next_angle[b.stream], 720.0)) > 0.5 * std::abs(step))
        ++lost;
      next_angle[b.stream] = b.data[(b.frames - 1) * b.channels] + step;
    }
  }
  return lost + static_cast<int>(reader.damaged());
}

// A file's whole text or bytes (a process's log, shown when it did not end as expected; a recording).
using noisemon::test::slurp;

// A copy of a log less one raw block of `stream` (raw_block_t::STREAM_*), from the middle of the recording.
bool copy_without_a_block(const std::string& log, const std::string& copy, int stream) {
  std::vector<std::pair<std::size_t, std::size_t>> blocks;  // each event's first byte and end
  {
    noisemon::drivers::formats::LcmLogReader reader{std::filesystem::path(log)};
    noisemon::drivers::formats::LcmLogEvent e;
    while (reader.next(e)) {
      noisemon::raw_block_t b;
      if (e.channel == "NOISEMON_RAW" && b.decode(e.data, 0, e.datalen) >= 0 && b.stream == stream)
        blocks.emplace_back(e.offset, e.offset + 28 + e.channel.size() + static_cast<std::size_t>(e.datalen));
    }
  }
  if (blocks.size() < 3) return false;
  const auto [from, to] = blocks[blocks.size() / 2];
  const std::string bytes = slurp(log);
  std::ofstream out(copy, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(from));
  out.write(bytes.data() + to, static_cast<std::streamsize>(bytes.size() - to));
  return static_cast<bool>(out);
}

// A cycle's flags for samples or crank-angle edges lost, or its filters settling after such a loss.
constexpr int kLostDataFlags = static_cast<int>(noisemon::cycle_report_t::CYCLE_GAP) |
                               static_cast<int>(noisemon::cycle_report_t::CYCLE_ANGLE_GAP) |
                               static_cast<int>(noisemon::cycle_report_t::CYCLE_SETTLING);

// How the cycles a subscriber received live came out again from a recording of the raw streams.
struct Replayed {
  int identical = 0;  // the same line, to the last printed digit
  int flagged = 0;    // different, and flagged: samples or crank-angle edges lost, or its filters settling after that
  int missing = 0;    // not there (a cycle whose samples were lost is dropped)
};

// Each live cycle is in `replayed` as it was, or flagged for lost data, or absent: never different without a flag.
Replayed compare_with_live(const std::string& live, const std::string& replayed) {
  const auto expected = csv_lines(live), got = csv_lines(replayed);
  Replayed r;
  for (const auto& [instant, line] : expected) {
    const auto it = got.find(instant);
    if (it == got.end()) {
      ++r.missing;
    } else if (without_cycle_number(it->second) == without_cycle_number(line)) {
      ++r.identical;
    } else if ((flags_of(it->second) & kLostDataFlags) != 0) {
      ++r.flagged;
    } else {
      ADD_FAILURE() << replayed << ": the cycle of " << instant
                    << " us differs from the live report without a flag\n  live:     " << line
                    << "\n  replayed: " << it->second;
    }
  }
  return r;
}

// `noisemon replay` of a recording of `cycles` cycles, compared with the live ones, the counts printed under `what`.
Replayed replay_against_live(const std::string& log, int cycles, const std::string& live, const char* what) {
  const std::string csv = log + ".csv";
  const pid_t replay = spawn({NOISEMON_PATH, "replay", log, "--csv", csv, "--no-progress"}, "/dev/null");
  EXPECT_EQ(wait_for(replay, allowance(kStartUp + engine_time(cycles))), 0);
  const Replayed r = compare_with_live(live, csv);
  std::printf("%s: %d identical, %d flagged, %d dropped\n", what, r.identical, r.flagged, r.missing);
  std::fflush(stdout);  // before the next fork, whose child would write it again
  return r;
}

std::string write_config(const std::string& name, const std::string& model, const std::string& true_block) {
  const std::string path = noisemon::test::unique_temp_dir() + "/" + name + ".toml";
  std::ofstream(path) << noisemon::test::sim_pacing_toml() << "[model]\npreset = \"" << model
                      << "\"\n[sim.true_block]\npreset = \"" << true_block << "\"\n";
  return path;
}

// A configuration with only the build's pacing of the virtual engine (tests/sanitizer.hpp), and `extra`.
std::string pacing_config(const std::string& name, const std::string& extra = "") {
  const std::string path = noisemon::test::unique_temp_dir() + "/" + name + ".toml";
  std::ofstream(path) << noisemon::test::sim_pacing_toml() << extra;
  return path;
}

// Rings for 5 s instead of 0.5 s: the raw blocks on their way to the bus (twice a driver ring), and the blocks a
// daemon reads from the bus, wait through a second or more of a thread descheduled on a loaded machine, so a
// recording and its playback hold every block. The daemon's lossy overrun (counted, never blocking the
// processing) is the fault tests' business, not this comparison's.
constexpr const char* kRoomyRings = "[processing]\nring_seconds = 5\n";

struct Session {
  std::vector<Row> rows;
  int daemon_status, watch_status;
};

// Starts the subscriber, then the daemon with --cycles; returns what the subscriber received.
Session run_session(const std::string& name, const std::string& model, const std::string& true_block, int reports) {
  const std::string csv = noisemon::test::unique_temp_dir() + "/" + name + ".csv";
  std::remove(csv.c_str());
  const pid_t watch = spawn({NOISEMON_PATH, "watch", "--lcm", kLcmUrl, "--count", std::to_string(reports), "--timeout",
                             kWatchTimeout, "--csv", csv},
                            noisemon::test::unique_temp_dir() + "/" + name + ".watch.txt");
  std::this_thread::sleep_for(allowance(kSubscribed));  // subscribed before the first report
  const int cycles = reports + 10;
  const pid_t daemon = spawn({NOISEMOND_PATH, "--config", write_config(name, model, true_block), "--lcm", kLcmUrl,
                              "--cycles", std::to_string(cycles)},
                             noisemon::test::unique_temp_dir() + "/" + name + ".daemon.txt");
  Session s;
  s.watch_status = wait_for(watch, allowance(kStartUp + engine_time(reports)));
  s.daemon_status = wait_for(daemon, allowance(kStartUp + engine_time(cycles)));
  s.rows = read_csv(csv);
  return s;
}

// The expected gap, computed offline without the daemon, its sim, resamplers, rings or LCM: the sim's default
// nominal cycle (3050 rpm, SOI 18 deg, no load), repeated at constant speed and sampled at 40 kHz, drives both
// block models; the difference of their A-weighted overall levels is what the daemon should report as
// predicted - measured when the engine's true block is `true_block` and the daemon's model is linear.
double offline_lpa_difference(const std::string& true_block) {
  constexpr double fs = 40000.0, rpm = 3050.0;
  noisemon::model::engine::EngineCycle cycle;
  cycle.compute(noisemon::model::engine::OperatingCondition{});
  noisemon::model::BlockModel linear(noisemon::model::preset("linear"), fs);
  noisemon::model::BlockModel truth(noisemon::model::preset(true_block), fs);
  noisemon::dsp::ThirdOctaveBank bank(fs, 2);
  const std::size_t n = static_cast<std::size_t>(1.6 * fs), settle = static_cast<std::size_t>(0.8 * fs);
  std::vector<double> u(n), y_lin(n), y_true(n), frames(2 * n);
  for (std::size_t k = 0; k < n; ++k) {
    const double theta = -360.0 + 6.0 * rpm * static_cast<double>(k) / fs;
    u[k] = cycle.pressure_pa(std::fmod(theta + 360.0, 720.0) - 360.0);
  }
  linear.process(u.data(), y_lin.data(), n);
  truth.process(u.data(), y_true.data(), n);
  for (std::size_t k = 0; k < n; ++k) {
    frames[2 * k] = y_lin[k];
    frames[2 * k + 1] = y_true[k];
  }
  bank.process(frames.data(), settle);
  std::vector<double> ms(2 * bank.band_count());
  bank.take_mean_square(ms.data());
  bank.process(frames.data() + 2 * settle, n - settle);
  bank.take_mean_square(ms.data());
  double sum[2] = {0, 0};
  for (int c = 0; c < 2; ++c)
    for (std::size_t b = 0; b < bank.band_count(); ++b)
      sum[c] += ms[c * bank.band_count() + b] *
                std::pow(10.0, noisemon::dsp::a_weighting_db(bank.bands()[b].exact_mid_hz) / 10);
  return 10 * std::log10(sum[0] / sum[1]);
}

}  // namespace

TEST(EndToEnd, MeasuredAndPredictedAgreeWhenTheModelIsTheTrueBlock) {
  NOISEMON_REQUIRE_NAMESPACE();
  const Session s = run_session("same", "linear", "linear", 60);
  EXPECT_EQ(s.watch_status, 0);
  EXPECT_EQ(s.daemon_status, 0);
  ASSERT_GE(s.rows.size(), 50u);
  for (const Row& r : s.rows) {
    EXPECT_NEAR(r.lpa_pred, r.lpa_meas, 0.5) << "cycle " << r.cycle;
    // LW(A) adds 10 lg(2 pi r^2) and C1 + C2 at 23 deg C, 101.325 kPa (5 lg(296.15 / 314) + 15 lg(296.15 / 296), by
    // hand) over ISO 3744's 100 Hz ... 10 kHz, which hold all but a few hundredths of a dB of the engine's sound.
    const double lw_over_lp = 10 * std::log10(2 * M_PI * 1.75 * 1.75) - 0.1271 + 0.0033;
    EXPECT_LE(r.lwa_pred - r.lpa_pred, lw_over_lp + 1e-3);
    EXPECT_GE(r.lwa_pred - r.lpa_pred, lw_over_lp - 0.1);
    EXPECT_NEAR(r.speed, 3050.0, 3050.0 * 0.03);  // the sim's default idle speed, with its ripple
    EXPECT_DOUBLE_EQ(r.soi, 18.0);
    EXPECT_GT(r.lpa_meas, 40.0);  // well above the background floor: the engine is heard
  }
  // Consecutive cycle indices: nothing dropped on the way.
  for (std::size_t i = 1; i < s.rows.size(); ++i) EXPECT_EQ(s.rows[i].cycle, s.rows[i - 1].cycle + 1);
}

// The last cycle the daemon's live display printed (-1: none): its lines that are not headers start with the cycle.
long long last_printed_cycle(const std::string& log) {
  std::ifstream in(log);
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty() && line.find("cycle") == std::string::npos && line.find("rpm") == std::string::npos) last = line;
  std::stringstream s(last);
  long long last_cycle = -1;
  s >> last_cycle;
  return last_cycle;
}

TEST(EndToEnd, SigintPublishesTheLastCompleteCycleAndExitsCleanly) {
  NOISEMON_REQUIRE_NAMESPACE();
  const std::string csv = noisemon::test::unique_temp_dir() + "/sigint.csv";
  const pid_t watch =
      spawn({NOISEMON_PATH, "watch", "--lcm", kLcmUrl, "--timeout", kWatchTimeout, "--csv", csv}, "/dev/null");
  std::this_thread::sleep_for(allowance(kSubscribed));
  const std::string log = noisemon::test::unique_temp_dir() + "/sigint.daemon.txt";
  const pid_t daemon = spawn({NOISEMOND_PATH, "--config", pacing_config("sigint"), "--lcm", kLcmUrl, "--live"}, log);
  // Interrupted in the middle of the run, once the subscriber holds 30 cycles.
  constexpr std::size_t kCycles = 30;
  const bool reached =
      wait_until([&] { return read_csv(csv).size() >= kCycles; }, allowance(kStartUp + engine_time(kCycles)));
  kill(daemon, SIGINT);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(wait_for(daemon, allowance(1s)), 0);
  // The cycle in progress is finished or dropped at once: promptly on the wall clock (a sanitizer's slowdown aside).
  if (!noisemon::test::kSanitized) {
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 3s);
  }
  ASSERT_TRUE(reached) << "the subscriber did not receive " << kCycles << " cycles";
  // The live display printed the same cycles the subscriber received, the last one included.
  const long long last_cycle = last_printed_cycle(log);
  ASSERT_GE(last_cycle, 0) << "the live display printed no cycle";
  std::vector<Row> rows;
  EXPECT_TRUE(
      wait_until([&] { return !(rows = read_csv(csv)).empty() && rows.back().cycle >= last_cycle; }, allowance(1s)));
  kill(watch, SIGINT);
  EXPECT_EQ(wait_for(watch, allowance(1s)), 0);
  ASSERT_FALSE(rows.empty());
  EXPECT_EQ(rows.back().cycle, last_cycle);
}

TEST(EndToEnd, StatusIsPublishedEverySecondWithHealthyThreads) {
  NOISEMON_REQUIRE_NAMESPACE();
  const std::string out = noisemon::test::unique_temp_dir() + "/status.txt";
  const pid_t daemon = spawn({NOISEMOND_PATH, "--config", pacing_config("status"), "--lcm", kLcmUrl}, "/dev/null");
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t watch =
      spawn({NOISEMON_PATH, "watch", "--status", "--lcm", kLcmUrl, "--count", "3", "--timeout", kWatchTimeout}, out);
  EXPECT_EQ(wait_for(watch, allowance(kStartUp + 3s)), 0);
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  kill(daemon, SIGTERM);
  EXPECT_EQ(wait_for(daemon, allowance(1s)), 0);
  EXPECT_GE(elapsed, 1.5);  // three messages at 1 Hz take at least two periods
  std::ifstream in(out);
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  EXPECT_NE(s.find("source=sim"), std::string::npos) << s;
  EXPECT_NE(s.find("processing=running"), std::string::npos) << s;
  EXPECT_NE(s.find("lcm=running"), std::string::npos) << s;
  EXPECT_EQ(s.find("FAILED"), std::string::npos) << s;
  EXPECT_NE(s.find("pressure="), std::string::npos) << s;
  EXPECT_NE(s.find("mics="), std::string::npos) << s;
}

class ModelMismatch : public ::testing::TestWithParam<std::pair<const char*, double>> {};

TEST_P(ModelMismatch, PredictedMinusMeasuredIsTheOfflineGap) {
  NOISEMON_REQUIRE_NAMESPACE();
  const auto [true_block, tolerance_db] = GetParam();
  const double expected = offline_lpa_difference(true_block);
  ASSERT_GT(std::abs(expected), 0.3) << "the presets must differ audibly for this test to mean anything";
  const Session s = run_session(std::string("mismatch_") + true_block, "linear", true_block, 50);
  EXPECT_EQ(s.daemon_status, 0);
  ASSERT_GE(s.rows.size(), 50u);
  double mean = 0;
  for (const Row& r : s.rows) mean += (r.lpa_pred - r.lpa_meas) / static_cast<double>(s.rows.size());
  std::printf("%s: predicted - measured %.3f dB over %zu cycles, offline %.3f dB\n", true_block, mean, s.rows.size(),
              expected);
  EXPECT_NEAR(mean, expected, tolerance_db) << true_block;
  for (const Row& r : s.rows) EXPECT_NEAR(r.lpa_pred - r.lpa_meas, expected, 2 * tolerance_db) << "cycle " << r.cycle;
}

// nl_damper is the thesis's best model and close to the linear one (~0.6 dB); the nonlinear spring is far off.
INSTANTIATE_TEST_SUITE_P(Presets, ModelMismatch,
                         ::testing::Values(std::pair{"nl_damper", 0.2}, std::pair{"nl_spring_damper", 0.5}),
                         [](const auto& info) { return std::string(info.param.first); });

TEST(EndToEnd, SystemdHearsReadyOnceDriversRunAndStoppingOnSigterm) {
  NOISEMON_REQUIRE_NAMESPACE();
  // Play systemd's part: a datagram socket named by NOTIFY_SOCKET, as for a Type=notify unit.
  const std::string path = noisemon::test::unique_temp_dir() + "/notify.sock";
  std::remove(path.c_str());
  const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
  ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  const auto quiet = allowance(kStartUp);  // the longest the daemon is silent: its start-up
  timeval tv{quiet.count() / 1000, 1000 * (quiet.count() % 1000)};
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  setenv("NOTIFY_SOCKET", path.c_str(), 1);
  const pid_t daemon = spawn({NOISEMOND_PATH, "--config", pacing_config("notify"), "--lcm", kLcmUrl}, "/dev/null");
  unsetenv("NOTIFY_SOCKET");
  // The notifications until one holds `what` (STATUS= lines come once a second, from the start); false after a
  // silence longer than the daemon's start-up.
  const auto wait_for_notification = [&](const std::string& what) {
    char buf[512] = {};
    for (ssize_t n; (n = recv(fd, buf, sizeof buf - 1, 0)) > 0;)
      if (std::string(buf, static_cast<std::size_t>(n)).find(what) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(wait_for_notification("READY=1")) << "no READY=1";
  kill(daemon, SIGTERM);
  EXPECT_TRUE(wait_for_notification("STOPPING=1")) << "no STOPPING=1";
  EXPECT_EQ(wait_for(daemon, allowance(1s)), 0);
  close(fd);
}

TEST(EndToEnd, MissingMulticastRouteIsAClearError) {
  NOISEMON_REQUIRE_NAMESPACE();
  // A fresh namespace of its own has no multicast route: the daemon must say what failed and exit 1.
  const std::string log = noisemon::test::unique_temp_dir() + "/badlcm.txt";
  const pid_t pid = fork();
  if (pid == 0) {
    if (!std::freopen(log.c_str(), "w", stderr) || unshare(CLONE_NEWNET) != 0) _exit(126);
    execl(NOISEMOND_PATH, NOISEMOND_PATH, static_cast<char*>(nullptr));
    _exit(127);
  }
  EXPECT_EQ(wait_for(pid, allowance(kStartUp)), 1);
  std::ifstream in(log);
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_NE(text.str().find("cannot open LCM"), std::string::npos) << text.str();
}

// The standard tools on the bus: lcm-logger records the session, `noisemon replay` and lcm-logplayer into a daemon
// give the live reports back. Every leg but the daemon's own counting crosses UDP multicast, which drops what a
// socket cannot hold while its reader waits for a core: so the test does not assume delivery. It asserts that what
// arrived came back exactly, that what was lost is accounted for (a recording missing raw blocks has its cycles
// flagged or dropped, never changed without a flag) and that, with nothing lost, every cycle came back.
TEST(EndToEnd, LcmLoggerRecordingReplaysToTheLiveReportsOfflineAndThroughLcmLogplayer) {
  NOISEMON_REQUIRE_NAMESPACE();
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string log = dir + "/session.lcmlog", live = dir + "/live.csv", replayed = dir + "/replayed.csv";
  std::remove(log.c_str());
  // The standard recorder, started before the daemon so the log holds the whole session.
  const pid_t logger = spawn({"/usr/bin/lcm-logger", "-q", "--lcm-url", kLcmUrl, log}, "/dev/null");
  constexpr int kCycles = 40;
  const std::string cycles = std::to_string(kCycles);
  const pid_t watch =
      spawn({NOISEMON_PATH, "watch", "--lcm", kLcmUrl, "--timeout", kWatchTimeout, "--csv", live}, "/dev/null");
  std::this_thread::sleep_for(allowance(kSubscribed));
  // A 0.5 deg encoder: its crank-angle stream adds 0.6 MB/s to the bus where the default 0.1 deg adds 2.9 MB/s; less
  // traffic, fewer losses to account for. The comparison is the same at any resolution.
  const std::string logged = dir + "/logged.toml";
  std::ofstream(logged) << "[sim]\n"
                        << (noisemon::test::kSanitized ? "paced = false\n" : "") << "encoder_resolution_deg = 0.5\n"
                        << kRoomyRings;
  const std::string daemon_log = dir + "/daemon.err";
  const pid_t daemon =
      spawn({NOISEMOND_PATH, "--config", logged, "--lcm", kLcmUrl, "--cycles", cycles, "--log-level", "debug"},
            "/dev/null", daemon_log);
  // It counts what it published.
  EXPECT_EQ(wait_for(daemon, allowance(kStartUp + engine_time(kCycles))), 0) << slurp(daemon_log);
  // The subscriber has what reached it once it holds every cycle or has heard nothing more for a while.
  wait_until([&] { return read_csv(live).size() >= kCycles; }, allowance(2 * kSubscribed));
  kill(watch, SIGINT);
  EXPECT_EQ(wait_for(watch, allowance(1s)), 0);
  std::this_thread::sleep_for(allowance(2 * kSubscribed));  // the recorder has the last messages
  kill(logger, SIGINT);
  wait_for(logger, allowance(1s));
  const auto live_cycles = csv_lines(live);
  ASSERT_GE(live_cycles.size(), kCycles / 2u) << "the live subscriber received too little to compare";

  const pid_t replay = spawn({NOISEMON_PATH, "replay", log, "--csv", replayed, "--no-progress"}, "/dev/null");
  ASSERT_EQ(wait_for(replay, allowance(kStartUp + engine_time(kCycles))), 0);
  const int lost = lost_raw_blocks(log);
  const Replayed offline = compare_with_live(live, replayed);
  std::printf(
      "lcm-logger's recording: %d raw block(s) lost; offline replay: %d of %zu live cycles identical, %d "
      "flagged, %d dropped\n",
      lost, offline.identical, live_cycles.size(), offline.flagged, offline.missing);
  std::fflush(stdout);  // before the next fork, whose child would write it again
  if (lost == 0) {
    EXPECT_EQ(offline.identical, static_cast<int>(live_cycles.size()));
  }
  EXPECT_GT(offline.identical, 0);

  // The real-tool round trip: lcm-logplayer plays the recorded streams into a daemon whose source is `lcm`.
  const std::string played = dir + "/played.csv";
  const std::string from_bus_log = dir + "/from_bus.err";
  // Its rings hold the whole recording, so it reads the bus at the pace played while its processing catches up
  // (under a sanitizer it cannot keep the recording's pace at all).
  const std::string from_bus_config = dir + "/from_bus.toml";
  std::ofstream(from_bus_config) << kRoomyRings << "[lcm]\nsession_timeout_s = " << allowance_s(7.5) << "\n";
  const pid_t from_bus =
      spawn({NOISEMOND_PATH, "--config", from_bus_config, "--source", "lcm", "--lcm", kLcmUrl, "--cycles", cycles},
            "/dev/null", from_bus_log);
  std::this_thread::sleep_for(allowance(2 * kSubscribed));
  // At half speed, slower again under a sanitizer: the bus carries half the recording's rate.
  const double speed = 0.5 / noisemon::test::kSanitizerSlowdown;
  // The recording's time is its events' span: an unpaced sanitized daemon may have taken longer than the engine
  // time to make it.
  const auto recorded = kStartUp + std::max(engine_time(kCycles), log_span(log));
  const auto playing = std::chrono::duration<double>(recorded) / speed;
  // The subscriber waits as long for the first played cycle as the player may take.
  const std::string play_timeout =
      std::to_string(allowance_s(kStartUp.count()) + playing.count() * noisemon::test::kLoadedMachineSlowdown);
  const pid_t watch2 =
      spawn({NOISEMON_PATH, "watch", "--lcm", kLcmUrl, "--timeout", play_timeout, "--csv", played}, "/dev/null");
  std::this_thread::sleep_for(allowance(kSubscribed));
  const pid_t player = spawn({"/usr/bin/lcm-logplayer", "--lcm-url", kLcmUrl, "-s", std::to_string(speed), "-e",
                              "NOISEMON_(RAW|OP|SESSION)", log},
                             "/dev/null");
  EXPECT_EQ(wait_for(player, std::chrono::duration_cast<std::chrono::milliseconds>(
                                 playing * noisemon::test::kLoadedMachineSlowdown)),
            0);
  // The daemon ends at its 40th cycle; a played block lost on the bus drops a cycle, and then it waits on: once it
  // has processed all that arrived, SIGINT ends it cleanly (tested above).
  const long long last_cycle = live_cycles.rbegin()->first;  // its instant
  int status = 0;
  bool ended = false;
  wait_until(
      [&] {
        ended = waitpid(from_bus, &status, WNOHANG) == from_bus;
        return ended || csv_lines(played).count(last_cycle) > 0;
      },
      allowance(recorded));
  if (ended) {
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << slurp(from_bus_log);
  } else {
    kill(from_bus, SIGINT);
    EXPECT_EQ(wait_for(from_bus, allowance(1s)), 0) << slurp(from_bus_log);
  }
  wait_until([&] { return csv_lines(played).count(last_cycle) > 0; }, allowance(2 * kSubscribed));
  kill(watch2, SIGINT);
  EXPECT_EQ(wait_for(watch2, allowance(1s)), 0);
  const Replayed through_bus = compare_with_live(live, played);
  std::printf("lcm-logplayer into a daemon: %d of %zu live cycles identical, %d flagged, %d dropped\n",
              through_bus.identical, live_cycles.size(), through_bus.flagged, through_bus.missing);
  std::fflush(stdout);
  EXPECT_GT(through_bus.identical, 0) << slurp(from_bus_log);

  // A log cut off in the middle still replays what it holds, without error.
  const std::string cut = dir + "/cut.lcmlog";
  const std::string bytes = slurp(log);
  std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2 + 7));
  const std::string cut_csv = dir + "/cut.csv";
  const pid_t replay_cut = spawn({NOISEMON_PATH, "replay", cut, "--csv", cut_csv, "--no-progress"}, "/dev/null");
  EXPECT_EQ(wait_for(replay_cut, allowance(kStartUp + engine_time(kCycles))), 0);
  const std::vector<Row> rows = read_csv(cut_csv);
  EXPECT_GE(rows.size(), 15u);
  EXPECT_LT(rows.size(), 40u);

  // The accounting above, proven on a loss made on purpose: the recording less one microphone block in its middle
  // replays with the cycle it falls in dropped and those after it flagged while the filters settle, never changed
  // without a flag.
  const std::string holed = dir + "/holed.lcmlog";
  ASSERT_TRUE(copy_without_a_block(log, holed, noisemon::raw_block_t::STREAM_MICS));
  EXPECT_EQ(lost_raw_blocks(holed), lost + 1);
  const Replayed with_hole = replay_against_live(holed, kCycles, live, "the recording less a block");
  EXPECT_GT(with_hole.missing + with_hole.flagged, offline.missing + offline.flagged);
  EXPECT_GT(with_hole.identical, 0);

  // And less one block of the crank-angle stream (edges lost: a cycle may go uncounted, so the replay numbers the
  // cycles after it differently; each is still the live one at its instant, or flagged, or absent).
  const std::string no_edges = dir + "/no_edges.lcmlog";
  ASSERT_TRUE(copy_without_a_block(log, no_edges, noisemon::raw_block_t::STREAM_PRESSURE_ANGLE));
  const Replayed without_edges = replay_against_live(no_edges, kCycles, live, "the recording less a block of edges");
  EXPECT_GT(without_edges.missing + without_edges.flagged, offline.missing + offline.flagged);
  EXPECT_GT(without_edges.identical, 0);
}

// Raw blocks that arrive between the session and the source's start (the pipeline is being built) or while a loaded
// machine leaves the receiving thread unscheduled wait in LCM's queue for the subscription; at LCM's default depth
// (30 messages) the rest were dropped and a played log lost its first cycles. Here 600 blocks arrive before start().
TEST(EndToEnd, AnLcmSourceKeepsTheBlocksThatArriveBeforeItStarts) {
  NOISEMON_REQUIRE_NAMESPACE();
  namespace nd = noisemon::drivers;
  constexpr std::int64_t kEpoch = 1'700'000'000'000'000;
  constexpr int kBlocks = 600;
  lcm::LCM bus(kLcmUrl);
  ASSERT_TRUE(bus.good());
  nd::StreamInfo info;
  info.epoch_utime = kEpoch;
  info.mic_count = 1;
  info.mic_positions_m = {{1, 0, 0}};
  const noisemon::session_t session = nd::formats::to_message(info, "test", kEpoch);
  std::atomic<bool> constructed{false};
  std::thread announcer([&] {  // the session until the source has it
    while (!constructed.load()) {
      bus.publish("NOISEMON_SESSION", &session);
      std::this_thread::sleep_for(20ms);
    }
  });
  nd::lcm::LcmSourceConfig config;
  config.url = kLcmUrl;
  config.session_timeout_s = allowance_s(2);
  std::unique_ptr<nd::Source> source;
  try {
    source = nd::lcm::make_lcm_source(config);
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
  constructed = true;
  announcer.join();
  ASSERT_TRUE(source);
  for (int i = 0; i < kBlocks; ++i) {
    nd::SampleBlock b;
    b.first_index = 8 * i;
    b.frames = 8;
    b.channels = 1;
    const noisemon::raw_block_t raw = nd::formats::to_message(b, noisemon::raw_block_t::STREAM_MICS, kEpoch);
    bus.publish("NOISEMON_RAW", &raw);
  }
  std::this_thread::sleep_for(allowance(200ms));  // LCM's own receiving thread queues them; nobody handles them yet
  nd::BlockRing pressure(16), mics(1024);
  nd::OperatingPointRing ops(16);
  source->start({&pressure, &mics, &ops});
  // Whatever arrives is delivered at once: the deadline only guards against a hang, and is reset by every block.
  std::size_t delivered = 0;
  auto deadline = std::chrono::steady_clock::now() + allowance(1s);
  for (nd::SampleBlock b; delivered < kBlocks && std::chrono::steady_clock::now() < deadline;) {
    if (mics.read(&b, 1) == 1) {
      EXPECT_EQ(b.first_index, static_cast<std::int64_t>(8 * delivered));
      ++delivered;
      deadline = std::chrono::steady_clock::now() + allowance(1s);
    } else {
      std::this_thread::sleep_for(1ms);
    }
  }
  source->stop();
  EXPECT_EQ(delivered, static_cast<std::size_t>(kBlocks));
}
