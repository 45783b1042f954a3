// The one worker-thread type of the daemon (driver, processing and publishing threads), after ArduPilot's
// AP_HAL_Linux Thread: a named std::thread with a scheduling policy, its state published atomically, the first
// error it failed with, and a stop request its body polls.
//
// Names are what `top -H` and /proc/<pid>/task/<tid>/comm show, so they follow the Linux limit of 15 characters
// ("nm-pressure", "nm-processing"). The status name (DriverThreadStatus::name) is the longer one the status
// message has always used ("sim.encoder_pressure").
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "drivers/source.hpp"

namespace noisemon::drivers {

// How the kernel schedules one thread. A setting that cannot be applied fails the thread; it never falls back.
struct ThreadPolicy {
  int fifo_priority = 0;   // SCHED_FIFO priority 1..99; 0: normal scheduling (SCHED_OTHER)
  std::optional<int> cpu;  // run only on this CPU index; none: wherever the kernel likes
};

inline constexpr std::size_t kMaxThreadNameLength = 15;  // TASK_COMM_LEN - 1

class WorkerThread {
 public:
  // The body runs on the thread until it returns (state kStopped) or throws (kFailed, the exception's text as
  // the error). It polls `stop` and returns soon after it turns true.
  using Body = std::function<void(const std::atomic<bool>& stop)>;

  explicit WorkerThread(std::string status_name);
  ~WorkerThread();  // stop()
  WorkerThread(const WorkerThread&) = delete;
  WorkerThread& operator=(const WorkerThread&) = delete;

  // Clears the previous run's state (kRunning, no error, no blocks) and starts the thread, which names itself
  // `name`, applies `policy`, then runs `body`. A policy the kernel refuses fails the thread before the body
  // runs, with an error naming the thread, the setting and what it needs ("thread nm-processing: SCHED_FIFO
  // priority 80 refused (EPERM): needs CAP_SYS_NICE or LimitRTPRIO=80 or more ..."). std::invalid_argument for
  // a name that is empty or longer than 15 characters, std::logic_error while a previous thread is not joined.
  void start(const std::string& name, const ThreadPolicy& policy, Body body);
  void request_stop() { stop_.store(true); }
  void join();
  void stop();  // request_stop(), join()

  bool joinable() const { return thread_.joinable(); }
  bool stop_requested() const { return stop_.load(std::memory_order_relaxed); }
  ThreadState state() const { return state_.load(); }
  const std::string& thread_name() const { return thread_name_; }

  // Progress shown in the status (blocks or items the thread delivered in this run).
  void set_blocks_written(std::uint64_t n) { blocks_.store(n, std::memory_order_relaxed); }
  void add_blocks_written(std::uint64_t n = 1) { blocks_.fetch_add(n, std::memory_order_relaxed); }
  std::uint64_t blocks_written() const { return blocks_.load(std::memory_order_relaxed); }

  // Safe from any thread; a status whose state is kFailed always carries the error.
  DriverThreadStatus status() const;

 private:
  void run(const ThreadPolicy& policy, const Body& body);
  void fail(const std::string& error);

  const std::string status_name_;
  std::string thread_name_;  // written by start() before the thread exists
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<ThreadState> state_{ThreadState::kIdle};
  std::atomic<std::uint64_t> blocks_{0};
  mutable std::mutex error_mutex_;  // guards error_ and orders it before the kFailed state
  std::string error_;
};

// Locks every present and future page of the process in RAM (mlockall(MCL_CURRENT | MCL_FUTURE)), so no page
// fault on the per-sample path waits for the disk. Throws std::runtime_error saying what it needs
// (CAP_IPC_LOCK, or LimitMEMLOCK large enough).
void lock_memory();

}  // namespace noisemon::drivers
