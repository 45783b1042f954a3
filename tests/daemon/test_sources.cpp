// Source selection of the daemon: the lcm source's session wait ends after [lcm] session_timeout_s with an
// error naming the channel (an in-process memq:// LCM on which nobody publishes: no network involved), a
// missing comedi device or CAN interface is an error naming it (from make_source and from the noisemond
// process: exit status 1, message on stderr), [can] combines with the sim, and the driver counters reach
// `noisemon watch --status` (real processes over LCM in a private network namespace; needs root), and the
// microphones of an audio interface reach every cycle of a noisemond process.
#include "daemon/sources.hpp"

#include <lcm/lcm-cpp.hpp>

#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <thread>

#include "drivers/formats/stream_messages.hpp"
#include "drivers/lcm/lcm_source.hpp"
#include "tests/e2e/private_network.hpp"
#include "tests/sanitizer.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/required.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

using noisemon::daemon::Config;
using noisemon::daemon::make_source;
using noisemon::daemon::parse_config;

namespace {

using noisemon::test::allowance;
using noisemon::test::allowance_s;
using noisemon::test::kStartUp;
using namespace std::chrono_literals;

using noisemon::test::kNoisemon;
using noisemon::test::kNoisemond;

std::string write_file(const std::string& name, const std::string& text) {
  const std::string path = noisemon::test::unique_temp_dir() + "/" + name;
  std::ofstream(path) << text;
  return path;
}

// Runs a program with stdout and stderr to files; kills it after the timeout. Returns the exit status (-1: killed).
int run(const std::vector<std::string>& args, const std::string& out, const std::string& err,
        std::chrono::milliseconds timeout) {
  const pid_t pid = fork();
  if (pid == 0) {
    if (!std::freopen(out.c_str(), "w", stdout) || !std::freopen(err.c_str(), "w", stderr)) _exit(126);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  return -1;
}

constexpr const char* kComediMissing = R"(
[daemon]
source = "comedi"
[comedi.pressure]
device = "/dev/comedi-noisemon-missing"
sensitivity_mv_per_bar = 10.0
[comedi.encoder]
device = "/dev/comedi-noisemon-missing"
subdevice = 11
[comedi.mics]
device = "/dev/comedi-noisemon-missing-mics"
channels = [0, 1]
sensitivity_mv_per_pa = 50.0
)";

constexpr const char* kSpeedSignal = R"(
[[can.signal]]
field = "speed_rpm"
id = 0x0CF00400
extended = true
start_bit = 24
length = 16
byte_order = "intel"
factor = 0.125
)";

}  // namespace

TEST(Sources, LcmSourceWithoutSessionFailsAfterTheConfiguredTimeout) {
  Config c = parse_config("[daemon]\nsource = \"lcm\"\n[lcm]\nurl = \"memq://\"\nsession_timeout_s = 0.4\n", "t");
  const auto t0 = std::chrono::steady_clock::now();
  try {
    make_source(c);
    FAIL() << "an lcm source started without a session";
  } catch (const std::runtime_error& e) {
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const std::string what = e.what();
    EXPECT_NE(what.find("NOISEMON_SESSION"), std::string::npos) << what;
    EXPECT_NE(what.find("memq://"), std::string::npos) << what;
    EXPECT_GE(waited, 0.4);
    EXPECT_LT(waited, 0.4 + allowance_s(0.4));
  }
}

// As the daemon opens it, and at rest (the pressure on the card's timer, for calibrate and check).
TEST(Sources, MissingComediDeviceIsNamed) {
  for (const auto clock : {noisemon::daemon::PressureClock::kEncoder, noisemon::daemon::PressureClock::kAtRest}) {
    try {
      make_source(parse_config(kComediMissing, "t"), clock);
      ADD_FAILURE() << "opened a missing comedi device";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find("/dev/comedi-noisemon-missing"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(noisemon::daemon::comedi_source_config(parse_config(kComediMissing, "t"),
                                                     noisemon::daemon::PressureClock::kAtRest)
                  .at_rest);
  EXPECT_FALSE(noisemon::daemon::comedi_source_config(parse_config(kComediMissing, "t"),
                                                      noisemon::daemon::PressureClock::kEncoder)
                   .at_rest);
}

TEST(Sources, CanSectionCombinesWithTheSimAndMissingInterfaceIsNamed) {
  const std::string log = write_file("sources.log", "(1700000000.000000) can0 0CF00400#FFFFFF405FFFFFFF\n");
  auto s = make_source(parse_config("[can]\ncandump = \"" + log + "\"\npace = \"fast\"\n" + kSpeedSignal, "t"));
  EXPECT_EQ(s->name(), "sim+candump");
  EXPECT_EQ(s->info().mic_count, 10u);  // the sim's streams
  try {
    make_source(parse_config(std::string("[can]\ninterface = \"nmcan3\"\n") + kSpeedSignal, "t"));
    FAIL() << "opened a missing CAN interface";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'nmcan3'"), std::string::npos) << e.what();
  }
}

TEST(Noisemond, MissingComediDeviceExitsNonZeroNamingIt) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string cfg = write_file("missing.toml", kComediMissing);
  EXPECT_EQ(run({kNoisemond, "--config", cfg}, dir + "/missing.out", dir + "/missing.err", allowance(kStartUp)), 1);
  const std::string err = noisemon::test::slurp(dir + "/missing.err");
  EXPECT_NE(err.find("cannot open comedi device /dev/comedi-noisemon-missing"), std::string::npos) << err;
}

// The virtual engine's pressure with the microphones of an audio interface (the tests' virtual interface, through
// alsa-lib: 12 channels at 48 kHz on a crystal 80 ppm fast, a 1 kHz tone of 0.1 of full scale on every channel):
// behind 1 V of full scale and 50 mV/Pa the tone is 2 Pa of amplitude, 96.99 dB SPL, and 0 dB of A-weighting at
// 1 kHz leaves every cycle's measured Lp(A) there but the first's, in which the band filters start from rest.
TEST(Noisemond, MicrophonesFromAnAudioInterfaceCarryItsLevelToEveryCycle) {
  const std::string dir = noisemon::test::unique_temp_dir();
  write_file("cell.asoundrc", "pcm_type.nmtimed { lib \"" NOISEMON_ALSA_TIMED_DEVICE
                              "\" }\n"
                              "pcm.cell { type nmtimed rate 48000 channels 12 tone_hz 1000 amplitude 0.1 ppm 80 }\n");
  const std::string cfg = write_file("alsa.toml",
                                     "[daemon]\nmicrophones = \"alsa\"\n"
                                     "[alsa]\npcm = \"cell\"\nconfig_file = \"cell.asoundrc\"\nrate_hz = 48000\n"
                                     "channels = [0, 1, 2, 3, 4, 5, 6, 7, 8, 11]\nsensitivity_mv_per_pa = 50.0\n"
                                     "full_scale_v = 1.0\nperiod_frames = 480\nperiods = 100\n");
  // The interface's clock is real time: under a sanitizer on a loaded machine the daemon cannot keep its pace and
  // overruns, as a real one would (a ThreadSanitizer run published 12 cycles in 390 s beside two busy loops). Its
  // threads are what that build checks: a few cycles show them at work.
  const int wanted = noisemon::test::kSanitized ? 4 : 20;
  EXPECT_EQ(run({kNoisemond, "--config", cfg, "--lcm", "memq://", "--cycles", std::to_string(wanted), "--live"},
                dir + "/alsa.out", dir + "/alsa.err", allowance(kStartUp + 5s)),
            0)
      << noisemon::test::slurp(dir + "/alsa.err");
  std::istringstream out(noisemon::test::slurp(dir + "/alsa.out"));
  std::string line;
  int cycles = 0, checked = 0;
  while (std::getline(out, line)) {
    std::istringstream fields(line);
    long cycle = 0;
    double rpm = 0, soi = 0, measured = 0;
    if (!(fields >> cycle >> rpm >> soi >> measured)) continue;  // the header
    ++cycles;
    if (cycle == 0) continue;  // the band filters start from rest in it (flagged settling, as the next few are)
    ++checked;
    EXPECT_NEAR(measured, 96.99, 0.1) << line;
  }
  EXPECT_EQ(cycles, wanted) << noisemon::test::slurp(dir + "/alsa.out");
  EXPECT_EQ(checked, wanted - 1) << noisemon::test::slurp(dir + "/alsa.out");
  EXPECT_NE(noisemon::test::slurp(dir + "/alsa.err").find("microphones from alsa"), std::string::npos);
}

TEST(Noisemond, LcmSourceWithoutSessionExitsNonZeroAfterTheTimeout) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string cfg = write_file("nosession.toml", "[lcm]\nsession_timeout_s = 0.3\n");
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(run({kNoisemond, "--config", cfg, "--source", "lcm", "--lcm", "memq://"}, dir + "/nosession.out",
                dir + "/nosession.err", allowance(kStartUp)),
            1);
  // The process's start-up and then the timeout (an ASan binary beside other load takes seconds to start).
  EXPECT_LT(std::chrono::steady_clock::now() - t0, allowance(kStartUp) + allowance(0.3s));
  const std::string err = noisemon::test::slurp(dir + "/nosession.err");
  EXPECT_NE(err.find("no noisemon.session_t on 'NOISEMON_SESSION'"), std::string::npos) << err;
}

TEST(Noisemond, DriverCountersAppearInWatchStatusAndTheRollingStatisticsInWatchStats) {
  NOISEMON_REQUIRE(geteuid() == 0, "root, for a private network namespace (unshare -n)");
  // The daemon and the subscriber in a private network namespace of their own: nothing leaves the machine.
  const std::string dir = noisemon::test::unique_temp_dir();  // made here: the child writes where we read
  const pid_t pid = fork();
  if (pid == 0) {
    if (unshare(CLONE_NEWNET) != 0 || std::system("ip link set lo up && ip route add 224.0.0.0/4 dev lo") != 0)
      _exit(125);
    const std::string log = write_file("status.log",
                                       "(1700000000.000000) can0 0CF00400#FFFFFF405FFFFFFF\n"
                                       "garbage\n"
                                       "(1700000000.100000) can0 0CF00400#FFFFFF00640000FF\n");
    const std::string cfg = write_file(
        "status.toml", noisemon::test::sim_pacing_toml() + "[can]\ncandump = \"" + log + "\"\n" + kSpeedSignal);
    const std::string url = noisemon::test::kLcmUrl;  // tests/e2e/private_network.hpp says why
    const pid_t daemon = fork();
    if (daemon == 0) {
      if (!std::freopen((dir + "/daemon.err").c_str(), "w", stderr)) _exit(126);
      execl(kNoisemond.c_str(), kNoisemond.c_str(), "--config", cfg.c_str(), "--lcm", url.c_str(),
            static_cast<char*>(nullptr));
      _exit(127);
    }
    // Status messages come once a second, the statistics with the cycles: the longest silence is the start-up.
    const std::string timeout = std::to_string(allowance_s(kStartUp.count()));
    const int watch = run({kNoisemon, "watch", "--status", "--lcm", url, "--count", "2", "--timeout", timeout},
                          dir + "/status.out", dir + "/status.err", allowance(kStartUp + 2s));
    const int stats = run({kNoisemon, "watch", "--stats", "--lcm", url, "--count", "1", "--timeout", timeout},
                          dir + "/stats.out", dir + "/stats.err", allowance(kStartUp));
    kill(daemon, SIGTERM);
    int status = 0;
    waitpid(daemon, &status, 0);
    std::printf("watch --status: %d, watch --stats: %d, noisemond: %d\n", watch, stats,
                WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status));
    std::fflush(stdout);
    _exit(watch == 0 && stats == 0 && WIFEXITED(status) && WEXITSTATUS(status) == 0 ? 0 : 1);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_NE(WEXITSTATUS(status), 125) << "cannot set up a private network namespace";
  const std::string out = noisemon::test::slurp(dir + "/status.out");
  EXPECT_EQ(WEXITSTATUS(status), 0) << out << noisemon::test::slurp(dir + "/status.err")
                                    << noisemon::test::slurp(dir + "/stats.err")
                                    << noisemon::test::slurp(dir + "/daemon.err");
  EXPECT_NE(out.find("source=sim+candump"), std::string::npos) << out;
  EXPECT_NE(out.find("candump.replay="), std::string::npos) << out;
  EXPECT_NE(out.find("counters:"), std::string::npos) << out;
  EXPECT_NE(out.find("candump.malformed_lines=1"), std::string::npos) << out;
  EXPECT_NE(out.find("candump.decoded_frames=2"), std::string::npos) << out;
  // The rolling statistics of the cycles so far (the window is 100 by default; the daemon ran a few seconds).
  const std::string stats = noisemon::test::slurp(dir + "/stats.out");
  EXPECT_NE(stats.find("of 100 cycles"), std::string::npos) << stats;
  EXPECT_NE(stats.find("Leq(A) measured"), std::string::npos) << stats;
  EXPECT_NE(stats.find("imep_net_bar"), std::string::npos) << stats;
  EXPECT_NE(stats.find("(energy mean)"), std::string::npos) << stats;
}

TEST(LcmSource, BlocksOfAnotherSessionAreCountedNotMixedIn) {
  // A multi-run log played with lcm-logplayer carries a second session (another epoch) after the first: its
  // frame indices restart on another time base, so the daemon's lcm source must not feed them into the rings
  // of the first. Real LCM (udpm) in a private network namespace; the publisher is a second LCM instance.
  NOISEMON_REQUIRE(geteuid() == 0, "root, for a private network namespace (unshare -n)");
  const pid_t pid = fork();
  if (pid == 0) {
    if (unshare(CLONE_NEWNET) != 0 || std::system("ip link set lo up && ip route add 224.0.0.0/4 dev lo") != 0)
      _exit(125);
    const std::string url = noisemon::test::kLcmUrl;  // tests/e2e/private_network.hpp says why
    lcm::LCM pub(url);
    if (!pub.good()) _exit(124);
    noisemon::drivers::StreamInfo a;
    a.epoch_utime = 1'700'000'000'000'000;
    const noisemon::session_t session = noisemon::drivers::formats::to_message(a, "test", a.epoch_utime, "run_a");
    std::atomic<bool> constructed{false};
    std::thread announcer([&] {  // the source's constructor waits for the session
      while (!constructed) {
        pub.publish("NOISEMON_SESSION", &session);
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    });
    noisemon::drivers::lcm::LcmSourceConfig lc;
    lc.url = url;
    lc.session_timeout_s = allowance_s(1.25);
    std::unique_ptr<noisemon::drivers::Source> src;
    try {
      src = noisemon::drivers::lcm::make_lcm_source(lc);
    } catch (...) {
      constructed = true;
      announcer.join();
      _exit(3);
    }
    constructed = true;
    announcer.join();
    noisemon::drivers::BlockRing pressure(64), mics(64);
    noisemon::drivers::OperatingPointRing ops(16);
    src->start({&pressure, &mics, &ops});
    noisemon::drivers::SampleBlock b;
    b.frames = 4;
    b.channels = noisemon::drivers::kPressureStreamChannels;
    for (std::size_t f = 0; f < b.frames; ++f) {
      b.data[f * b.channels + noisemon::drivers::kPressureChannel] = 1e5;
      b.data[f * b.channels + noisemon::drivers::kCrankChannel] = 0.0;  // in range: the blocks fit their session
    }
    for (int k = 0; k < 5; ++k) {
      b.first_index = 4 * (k % 2);
      const std::int64_t epoch = k < 2 ? a.epoch_utime : a.epoch_utime + 60'000'000;  // blocks 2..4: the next run
      const noisemon::raw_block_t m =
          noisemon::drivers::formats::to_message(b, noisemon::raw_block_t::STREAM_PRESSURE, epoch);
      pub.publish("NOISEMON_RAW", &m);
    }
    std::int64_t blocks = -1, other = -1;
    const auto deadline = std::chrono::steady_clock::now() + allowance(0.5s);  // five small messages on loopback
    while (std::chrono::steady_clock::now() < deadline && blocks + other < 5) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      for (const auto& c : src->counters()) {
        if (c.name == "lcm.blocks") blocks = c.value;
        if (c.name == "lcm.other_session_blocks") other = c.value;
      }
    }
    src->stop();
    std::size_t in_ring = 0;
    noisemon::drivers::SampleBlock out;
    while (pressure.read(&out, 1) == 1) ++in_ring;
    std::printf("blocks %lld, other session %lld, in the ring %zu\n", static_cast<long long>(blocks),
                static_cast<long long>(other), in_ring);
    _exit(blocks == 2 && other == 3 && in_ring == 2 ? 0 : 1);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_NE(WEXITSTATUS(status), 125) << "cannot set up a private network namespace";
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the source fed another session's blocks, or lost its own (status "
                                    << WEXITSTATUS(status) << ")";
}
