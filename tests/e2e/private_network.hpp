// What the end-to-end tests share: a private network namespace for the whole test program (nothing leaves this
// machine), and starting and reaping real processes.
#pragma once

#include <gtest/gtest.h>
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "tests/sanitizer.hpp"
#include "tests/support/required.hpp"

namespace noisemon::test {

// Every subscriber's socket holds 4 MB (the kernel's rmem_max here; LCM warns and takes what it may where it is less):
// all of the group's traffic, the raw streams too (2.7 MB/s), reaches each subscriber, and the default 208 kB held
// 80 ms of it, so a subscriber descheduled longer on a loaded 2-core machine lost packets (lcm-logger missed two
// cycles' raw blocks beside two CPU-bound processes). A real network's loss is what the fault tests inject.
inline const char* const kLcmUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304";

// Enters a private network namespace once for the whole test program, with loopback up and a multicast route.
class PrivateNetwork : public ::testing::Environment {
 public:
  void SetUp() override {
    if (geteuid() != 0) {
      reason = "needs root for a private network namespace (unshare -n)";
      return;
    }
    if (unshare(CLONE_NEWNET) != 0) {
      reason = std::string("unshare(CLONE_NEWNET) failed: ") + std::strerror(errno);
      return;
    }
    if (std::system("ip link set lo up && ip route add 224.0.0.0/4 dev lo") != 0) {
      reason = "cannot bring up loopback with a multicast route in the namespace";
      return;
    }
    ok = true;
  }
  static inline bool ok = false;
  static inline std::string reason;
};

// Skips without the namespace; fails instead under CI (tests/support/required.hpp), where it must be available.
#define NOISEMON_REQUIRE_NAMESPACE()                                                        \
  do {                                                                                      \
    if (!::noisemon::test::PrivateNetwork::ok) {                                            \
      if (::noisemon::test::under_ci()) FAIL() << ::noisemon::test::PrivateNetwork::reason; \
      GTEST_SKIP() << ::noisemon::test::PrivateNetwork::reason;                             \
    }                                                                                       \
  } while (0)

// Starts a program with its standard output in stdout_path and its standard error in stderr_path (empty:
// inherited).
inline pid_t spawn(const std::vector<std::string>& args, const std::string& stdout_path,
                   const std::string& stderr_path = "") {
  const pid_t pid = fork();
  if (pid == 0) {
    if (!stdout_path.empty() && !std::freopen(stdout_path.c_str(), "w", stdout)) _exit(126);
    if (!stderr_path.empty() && !std::freopen(stderr_path.c_str(), "w", stderr)) _exit(126);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

// Waits up to timeout for the child; then kills it (unless kill_after is false). Returns the exit status
// (128 + signal when killed by one), or -1 on timeout.
inline int wait_for(pid_t pid, std::chrono::milliseconds timeout, bool kill_after = true) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    int status = 0;
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (std::chrono::steady_clock::now() >= deadline) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  if (kill_after) {
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
  }
  return -1;
}

// Waits until `done` holds, polling; false when the deadline passed first.
template <class Condition>
bool wait_until(Condition done, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

}  // namespace noisemon::test
