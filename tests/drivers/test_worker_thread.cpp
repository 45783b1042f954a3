// The worker thread: its name is what the kernel shows, a failing body leaves its text in the status before the
// state says failed (hammered from another thread), stop() joins, and a scheduling policy either takes effect or
// fails the thread with an error naming the thread, the setting and what it needs. The refusals are also
// checked as an unprivileged user (a forked child that drops root), so they are exercised on a root CI machine.
#include "drivers/worker_thread.hpp"

#include <grp.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <thread>

#include "tests/sanitizer.hpp"

namespace nd = noisemon::drivers;

namespace {

void wait_while_running(const nd::WorkerThread& w) {
  // A thread seeing its stop flag.
  const auto deadline = std::chrono::steady_clock::now() + noisemon::test::allowance(std::chrono::seconds(1));
  while (w.state() == nd::ThreadState::kRunning && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

void idle_until_stopped(const std::atomic<bool>& stop) {
  while (!stop.load()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

std::string comm_of(pid_t tid) {
  std::ifstream in("/proc/self/task/" + std::to_string(tid) + "/comm");
  std::string name;
  std::getline(in, name);
  return name;
}

// Whether this process may put a thread under SCHED_FIFO at `priority` (tried on a throw-away thread).
bool may_use_fifo(int priority) {
  bool allowed = false;
  std::thread probe([&] {
    sched_param param{};
    param.sched_priority = priority;
    allowed = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  });
  probe.join();
  return allowed;
}

// An allowed CPU, and an index below CPU_SETSIZE that this process may not use.
std::pair<int, int> allowed_and_forbidden_cpu() {
  cpu_set_t set;
  CPU_ZERO(&set);
  EXPECT_EQ(sched_getaffinity(0, sizeof set, &set), 0);
  int allowed = -1, forbidden = -1;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
    if (CPU_ISSET(cpu, &set) && allowed < 0) allowed = cpu;
    if (!CPU_ISSET(cpu, &set)) forbidden = cpu;
  }
  return {allowed, forbidden};
}

// In a death-test child: no real-time or memory-lock allowance, and, when root, an ordinary user (which clears
// the capabilities CAP_SYS_NICE and CAP_IPC_LOCK).
void become_unprivileged() {
  const rlimit none{0, 0};
  if (setrlimit(RLIMIT_RTPRIO, &none) != 0 || setrlimit(RLIMIT_MEMLOCK, &none) != 0) {
    std::perror("setrlimit");
    std::_Exit(2);
  }
  const uid_t nobody = 65534;
  if (geteuid() == 0 && (setgroups(0, nullptr) != 0 || setresgid(nobody, nobody, nobody) != 0 ||
                         setresuid(nobody, nobody, nobody) != 0)) {
    std::perror("dropping root");
    std::_Exit(2);
  }
}

// Runs a worker with `policy` and prints its error on stderr; exits 0 when it failed before its body ran.
void run_refused_policy_and_exit(const nd::ThreadPolicy& policy) {
  bool body_ran = false;
  nd::WorkerThread w("test.refused");
  w.start("nm-test-refuse", policy, [&](const std::atomic<bool>&) { body_ran = true; });
  w.join();
  const nd::DriverThreadStatus s = w.status();
  std::fprintf(stderr, "%s\n", s.error.c_str());
  std::_Exit(s.state == nd::ThreadState::kFailed && !body_ran ? 0 : 1);
}

}  // namespace

TEST(WorkerThread, NameIsVisibleInProcWhileItRuns) {
  std::atomic<pid_t> tid{0};
  nd::WorkerThread w("test.named");
  w.start("nm-test-name", {}, [&](const std::atomic<bool>& stop) {
    tid = gettid();
    idle_until_stopped(stop);
  });
  while (tid.load() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(comm_of(tid), "nm-test-name");
  EXPECT_EQ(w.thread_name(), "nm-test-name");
  EXPECT_EQ(w.status().name, "test.named");  // the status keeps its own (longer) name
  EXPECT_EQ(w.status().state, nd::ThreadState::kRunning);
  w.stop();
  EXPECT_THROW(w.start("nm-sixteen-chars", {}, [](const std::atomic<bool>&) {}), std::invalid_argument);
  EXPECT_THROW(w.start("", {}, [](const std::atomic<bool>&) {}), std::invalid_argument);
}

TEST(WorkerThread, StopJoinsAndARunCanFollow) {
  std::atomic<bool> returned{false};
  nd::WorkerThread w("test.stop");
  EXPECT_EQ(w.status().state, nd::ThreadState::kIdle);
  auto body = [&](const std::atomic<bool>& stop) {
    w.add_blocks_written(3);
    idle_until_stopped(stop);
    returned = true;
  };
  w.start("nm-test-stop", {}, body);
  EXPECT_THROW(w.start("nm-test-stop", {}, body), std::logic_error);
  w.stop();
  EXPECT_TRUE(returned);  // joined: the body has returned
  EXPECT_FALSE(w.joinable());
  EXPECT_TRUE(w.stop_requested());
  EXPECT_EQ(w.status().state, nd::ThreadState::kStopped);
  EXPECT_EQ(w.status().blocks_written, 3u);
  w.stop();  // again: no effect
  returned = false;
  w.start("nm-test-stop", {}, body);
  EXPECT_FALSE(w.stop_requested());
  w.stop();
  EXPECT_TRUE(returned);
  EXPECT_EQ(w.status().blocks_written, 3u);  // counted from 0 again
}

TEST(WorkerThread, ThrowingBodyLeavesFailedWithTheExceptionsText) {
  nd::WorkerThread w("test.failing");
  w.start("nm-test-fail", {}, [](const std::atomic<bool>&) { throw std::runtime_error("comedi0: sensor unplugged"); });
  wait_while_running(w);
  const nd::DriverThreadStatus s = w.status();
  EXPECT_EQ(s.state, nd::ThreadState::kFailed);
  EXPECT_EQ(s.error, "comedi0: sensor unplugged");
  w.stop();
  EXPECT_EQ(w.status().state, nd::ThreadState::kFailed);  // stopping does not hide the failure
  // A new run starts clean.
  w.start("nm-test-fail", {}, [](const std::atomic<bool>& stop) { idle_until_stopped(stop); });
  EXPECT_EQ(w.status().error, "");
  w.stop();
  EXPECT_EQ(w.status().state, nd::ThreadState::kStopped);
}

TEST(WorkerThread, AReaderNeverSeesFailedWithoutTheError) {
  nd::WorkerThread w("test.hammered");
  std::atomic<bool> done{false};
  std::atomic<long> failed_seen{0}, failed_without_error{0};
  std::thread reader([&] {
    while (!done.load()) {
      const nd::DriverThreadStatus s = w.status();
      if (s.state != nd::ThreadState::kFailed) continue;
      ++failed_seen;
      if (s.error.empty()) ++failed_without_error;
    }
  });
  for (int run = 0; run < 300; ++run) {
    w.start("nm-test-hammer", {}, [run](const std::atomic<bool>&) {
      for (int i = 0; i < run % 7; ++i) std::this_thread::yield();  // vary where the failure meets the reader
      throw std::runtime_error("failure of run " + std::to_string(run));
    });
    w.join();
    EXPECT_EQ(w.status().error, "failure of run " + std::to_string(run));
  }
  done = true;
  reader.join();
  EXPECT_EQ(failed_without_error.load(), 0);
  EXPECT_GT(failed_seen.load(), 0);
}

// Priority 1, the lowest SCHED_FIFO priority, so that a granted request cannot starve this shared machine.
TEST(WorkerThread, FifoPriorityTakesEffectOrFailsNamingThreadSettingAndCapability) {
  const int priority = sched_get_priority_min(SCHED_FIFO);
  ASSERT_GE(sched_get_priority_max(SCHED_FIFO), priority);
  int policy_seen = -1, priority_seen = -1;
  nd::WorkerThread w("test.fifo");
  w.start("nm-test-fifo", {.fifo_priority = priority, .cpu = std::nullopt}, [&](const std::atomic<bool>&) {
    sched_param param{};
    pthread_getschedparam(pthread_self(), &policy_seen, &param);
    priority_seen = param.sched_priority;
  });
  w.join();
  const nd::DriverThreadStatus s = w.status();
  if (may_use_fifo(priority)) {
    EXPECT_EQ(s.state, nd::ThreadState::kStopped) << s.error;
    EXPECT_EQ(policy_seen, SCHED_FIFO);
    EXPECT_EQ(priority_seen, priority);
  } else {
    EXPECT_EQ(s.state, nd::ThreadState::kFailed);
    EXPECT_NE(
        s.error.find("thread nm-test-fifo: SCHED_FIFO priority 1 refused (EPERM): needs CAP_SYS_NICE or LimitRTPRIO"),
        std::string::npos)
        << s.error;
    EXPECT_EQ(policy_seen, -1);  // the body never ran
  }
}

TEST(WorkerThread, FifoPriorityRefusedToAnUnprivilegedProcess) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        become_unprivileged();
        run_refused_policy_and_exit({.fifo_priority = 80, .cpu = std::nullopt});
      },
      ::testing::ExitedWithCode(0),
      "thread nm-test-refuse: SCHED_FIFO priority 80 refused \\(EPERM\\): needs CAP_SYS_NICE or LimitRTPRIO=80 or more "
      "\\(RLIMIT_RTPRIO is 0\\)");
  EXPECT_EXIT(run_refused_policy_and_exit({.fifo_priority = 100, .cpu = std::nullopt}), ::testing::ExitedWithCode(0),
              "SCHED_FIFO priority 100 refused: out of range \\[1, 99\\]");
}

TEST(WorkerThread, CpuAffinityTakesEffectOrFailsNamingTheCpu) {
  const auto [allowed, forbidden] = allowed_and_forbidden_cpu();
  ASSERT_GE(allowed, 0);
  ASSERT_GE(forbidden, 0);
  std::atomic<int> cpu_seen{-1}, cpus_allowed{-1};
  nd::WorkerThread w("test.pinned");
  w.start("nm-test-cpu", {.cpu = allowed}, [&](const std::atomic<bool>&) {
    cpu_set_t set;
    CPU_ZERO(&set);
    pthread_getaffinity_np(pthread_self(), sizeof set, &set);
    cpus_allowed = CPU_COUNT(&set);
    cpu_seen = sched_getcpu();
  });
  w.join();
  EXPECT_EQ(w.status().state, nd::ThreadState::kStopped) << w.status().error;
  EXPECT_EQ(cpus_allowed, 1);
  EXPECT_EQ(cpu_seen, allowed);

  bool body_ran = false;
  w.start("nm-test-cpu", {.cpu = forbidden}, [&](const std::atomic<bool>&) { body_ran = true; });
  w.join();
  nd::DriverThreadStatus s = w.status();
  EXPECT_EQ(s.state, nd::ThreadState::kFailed);
  EXPECT_FALSE(body_ran);
  const std::string expected = "thread nm-test-cpu: CPU affinity to CPU " + std::to_string(forbidden) +
                               " refused (EINVAL): no such CPU among those this process may use (CPUs ";
  EXPECT_EQ(s.error.rfind(expected, 0), 0u) << s.error;

  w.start("nm-test-cpu", {.cpu = CPU_SETSIZE}, [&](const std::atomic<bool>&) { body_ran = true; });
  w.join();
  s = w.status();
  EXPECT_EQ(s.state, nd::ThreadState::kFailed);
  EXPECT_NE(s.error.find("CPU affinity to CPU " + std::to_string(CPU_SETSIZE) + " refused: not a CPU index"),
            std::string::npos)
      << s.error;
  EXPECT_FALSE(body_ran);
}

TEST(LockMemory, RefusedToAnUnprivilegedProcessWithAClearError) {
#if defined(NOISEMON_SANITIZE_ADDRESS) || defined(NOISEMON_SANITIZE_THREAD)
  GTEST_SKIP() << "the sanitizer replaces mlockall with a no-op that succeeds";
#endif
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        become_unprivileged();
        try {
          nd::lock_memory();
        } catch (const std::runtime_error& e) {
          std::fprintf(stderr, "%s\n", e.what());
          std::_Exit(0);
        }
        std::_Exit(1);
      },
      ::testing::ExitedWithCode(0),
      "cannot lock memory: mlockall\\(MCL_CURRENT \\| MCL_FUTURE\\) refused \\(EPERM\\): needs CAP_IPC_LOCK or "
      "LimitMEMLOCK=infinity \\(RLIMIT_MEMLOCK is 0 KiB\\)");
}
