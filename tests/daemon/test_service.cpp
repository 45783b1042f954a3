// noisemond as systemd runs it (Type=notify, WatchdogSec): the real binary, a notify socket of the test's own
// (NOTIFY_SOCKET, WATCHDOG_USEC), LCM in memory (memq://, nothing on the network). READY=1 once the drivers
// deliver, STATUS= lines, WATCHDOG=1 at a quarter of the period; SIGHUP with a broken file keeps the running
// configuration and says why, with a good one restarts (RELOADING=1, READY=1 again); SIGTERM ends with status 0.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/sanitizer.hpp"
#include "tests/support/programs.hpp"
#include "tests/support/text_file.hpp"
#include "tests/support/unique_temp.hpp"

namespace {

using noisemon::test::allowance;
using namespace std::chrono_literals;

using noisemon::test::kNoisemond;

class NotifySocket {
 public:
  explicit NotifySocket(const std::string& path) : path_(path) {
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    path.copy(a.sun_path, sizeof a.sun_path - 1);
    unlink(path.c_str());
    ok_ = fd_ >= 0 && bind(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a) == 0;
  }
  ~NotifySocket() {
    if (fd_ >= 0) close(fd_);
    unlink(path_.c_str());
  }
  bool ok() const { return ok_; }
  // Every datagram received until `done(got)` holds, or `timeout` passed.
  template <class Done>
  std::vector<std::string> collect(Done done, std::chrono::milliseconds timeout) {
    std::vector<std::string> got;
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!done(got) && std::chrono::steady_clock::now() < end) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 20) <= 0) continue;
      char buf[4096];
      const ssize_t n = recv(fd_, buf, sizeof buf, 0);
      if (n > 0) got.emplace_back(buf, static_cast<std::size_t>(n));
    }
    return got;
  }

 private:
  std::string path_;
  int fd_ = -1;
  bool ok_ = false;
};

int count(const std::vector<std::string>& messages, const std::string& what) {
  int n = 0;
  for (const auto& m : messages) n += m.find(what) != std::string::npos ? 1 : 0;
  return n;
}

}  // namespace

TEST(Service, ReadyStatusWatchdogAndAReloadThatKeepsTheRunningConfigurationWhenTheFileIsBroken) {
  const std::string dir = noisemon::test::unique_temp_dir();
  const std::string socket_path = "/tmp/noisemon-notify-" + std::to_string(getpid()) + ".sock";  // sun_path: 108 bytes
  NotifySocket notify(socket_path);
  ASSERT_TRUE(notify.ok());
  const std::string cfg = dir + "/noisemond.toml", err = dir + "/noisemond.err";
  std::ofstream(cfg) << noisemon::test::sim_pacing_toml() << "[model]\npreset = \"linear\"\n";
  const pid_t pid = fork();
  if (pid == 0) {
    setenv("NOTIFY_SOCKET", socket_path.c_str(), 1);
    setenv("WATCHDOG_USEC", "1000000", 1);
    unsetenv("WATCHDOG_PID");
    if (!std::freopen(err.c_str(), "w", stderr) || !std::freopen("/dev/null", "w", stdout)) _exit(126);
    execl(kNoisemond.c_str(), kNoisemond.c_str(), "--config", cfg.c_str(), "--lcm", "memq://",
          static_cast<char*>(nullptr));
    _exit(127);
  }
  struct Reaper {
    pid_t pid;
    ~Reaper() {
      if (kill(pid, 0) == 0) kill(pid, SIGKILL), waitpid(pid, nullptr, 0);
    }
  } reaper{pid};
  // Ready, a status with published cycles, and the 1 s watchdog fed (every 0.25 s once ready) six times: a few
  // seconds of the daemon's work.
  const std::vector<std::string> first = notify.collect(
      [](const auto& got) {
        return count(got, "READY=1") >= 1 && count(got, "cycles published") >= 1 && count(got, "WATCHDOG=1") >= 6;
      },
      allowance(4s));
  EXPECT_EQ(count(first, "READY=1"), 1) << noisemon::test::slurp(err);
  EXPECT_GE(count(first, "STATUS=acquiring: "), 1);
  EXPECT_GE(count(first, "cycles published"), 1);
  EXPECT_GE(count(first, "WATCHDOG=1"), 6);

  // A broken file: logged, nothing restarts, the watchdog keeps being fed.
  std::ofstream(cfg) << "[model\npreset = \"linear\"\n";
  kill(pid, SIGHUP);
  const auto kept = [&] {
    return noisemon::test::slurp(err).find("keeping the running configuration") != std::string::npos;
  };
  const std::vector<std::string> broken =
      notify.collect([&](const auto& got) { return count(got, "WATCHDOG=1") >= 3 && kept(); }, allowance(1.5s));
  EXPECT_EQ(count(broken, "RELOADING=1"), 0);
  EXPECT_GE(count(broken, "WATCHDOG=1"), 3);
  // A good one: the pipeline restarts with it and says READY again.
  std::ofstream(cfg) << noisemon::test::sim_pacing_toml() << "[model]\npreset = \"nl_damper\"\n";
  kill(pid, SIGHUP);
  const std::vector<std::string> good = notify.collect(
      [](const auto& got) { return count(got, "RELOADING=1") >= 1 && count(got, "READY=1") >= 1; }, allowance(4s));
  EXPECT_EQ(count(good, "RELOADING=1"), 1);
  EXPECT_EQ(count(good, "READY=1"), 1);

  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  const std::string log = noisemon::test::slurp(err);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << log;
  EXPECT_NE(log.find("SIGHUP: " + cfg), std::string::npos) << log;  // the parse error names the file
  EXPECT_NE(log.find("keeping the running configuration"), std::string::npos) << log;
  EXPECT_NE(log.find("restarting the pipeline"), std::string::npos) << log;
}
