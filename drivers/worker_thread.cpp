#include "drivers/worker_thread.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace noisemon::drivers {
namespace {

// The errno symbol an administrator looks up ("EPERM"), or the C library's text for the unexpected ones.
std::string error_name(int err) {
  switch (err) {
    case EPERM:
      return "EPERM";
    case EINVAL:
      return "EINVAL";
    case ENOMEM:
      return "ENOMEM";
    case ESRCH:
      return "ESRCH";
    case EAGAIN:
      return "EAGAIN";
    case ERANGE:
      return "ERANGE";
    default:
      return std::strerror(err);
  }
}

std::string soft_limit(int resource, const char* unit, rlim_t divisor) {
  rlimit limit{};
  if (getrlimit(resource, &limit) != 0) return "unknown";
  if (limit.rlim_cur == RLIM_INFINITY) return "unlimited";
  return std::to_string(limit.rlim_cur / divisor) + unit;
}

// The CPUs the calling thread may run on, as ranges: "0-3,6".
std::string allowed_cpus() {
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) != 0) return "unknown";
  std::string out;
  for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu) {
    if (!CPU_ISSET(cpu, &set)) continue;
    int last = cpu;
    while (last + 1 < CPU_SETSIZE && CPU_ISSET(last + 1, &set)) ++last;
    out += (out.empty() ? "" : ",") + std::to_string(cpu) + (last > cpu ? "-" + std::to_string(last) : "");
    cpu = last;
  }
  return out.empty() ? "none" : out;
}

void name_calling_thread(const std::string& name) {
  if (const int err = pthread_setname_np(pthread_self(), name.c_str()); err != 0)
    throw std::runtime_error("thread " + name + ": cannot set its name (" + error_name(err) + ")");
}

void pin_calling_thread(const std::string& name, int cpu) {
  const std::string what = "thread " + name + ": CPU affinity to CPU " + std::to_string(cpu);
  if (cpu < 0 || cpu >= CPU_SETSIZE)
    throw std::runtime_error(what + " refused: not a CPU index (0.." + std::to_string(CPU_SETSIZE - 1) + ")");
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  const int err = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
  if (err == 0) return;
  std::string why = what + " refused (" + error_name(err) + ")";
  if (err == EINVAL) why += ": no such CPU among those this process may use (CPUs " + allowed_cpus() + ")";
  throw std::runtime_error(why);
}

void make_calling_thread_fifo(const std::string& name, int priority) {
  const std::string what = "thread " + name + ": SCHED_FIFO priority " + std::to_string(priority);
  const int lowest = sched_get_priority_min(SCHED_FIFO), highest = sched_get_priority_max(SCHED_FIFO);
  if (priority < lowest || priority > highest)
    throw std::runtime_error(what + " refused: out of range [" + std::to_string(lowest) + ", " +
                             std::to_string(highest) + "]");
  sched_param param{};
  param.sched_priority = priority;
  const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (err == 0) return;
  std::string why = what + " refused (" + error_name(err) + ")";
  if (err == EPERM)
    why += ": needs CAP_SYS_NICE or LimitRTPRIO=" + std::to_string(priority) + " or more (RLIMIT_RTPRIO is " +
           soft_limit(RLIMIT_RTPRIO, "", 1) + ")";
  throw std::runtime_error(why);
}

void apply_thread_policy(const std::string& name, const ThreadPolicy& policy) {
  if (policy.cpu) pin_calling_thread(name, *policy.cpu);
  if (policy.fifo_priority != 0) make_calling_thread_fifo(name, policy.fifo_priority);
}

}  // namespace

WorkerThread::WorkerThread(std::string status_name) : status_name_(std::move(status_name)) {}

WorkerThread::~WorkerThread() { stop(); }

void WorkerThread::start(const std::string& name, const ThreadPolicy& policy, Body body) {
  if (name.empty() || name.size() > kMaxThreadNameLength)
    throw std::invalid_argument("thread name '" + name + "': 1.." + std::to_string(kMaxThreadNameLength) +
                                " characters (the kernel's limit)");
  if (thread_.joinable()) throw std::logic_error("thread " + name + ": start() while running; stop() first");
  thread_name_ = name;
  stop_.store(false);
  blocks_.store(0);
  {
    std::lock_guard lock(error_mutex_);
    error_.clear();
    state_.store(ThreadState::kRunning);
  }
  try {
    thread_ = std::thread([this, policy, body = std::move(body)] { run(policy, body); });
  } catch (...) {
    state_.store(ThreadState::kIdle);
    throw;
  }
}

void WorkerThread::join() {
  if (thread_.joinable()) thread_.join();
}

void WorkerThread::stop() {
  request_stop();
  join();
}

DriverThreadStatus WorkerThread::status() const {
  std::lock_guard lock(error_mutex_);
  return {status_name_, state_.load(), blocks_.load(std::memory_order_relaxed), error_};
}

void WorkerThread::run(const ThreadPolicy& policy, const Body& body) {
  try {
    name_calling_thread(thread_name_);
    apply_thread_policy(thread_name_, policy);
    body(stop_);
  } catch (const std::exception& e) {
    fail(*e.what() ? e.what() : "thread " + thread_name_ + ": failed (an exception without a message)");
    return;
  } catch (...) {
    fail("thread " + thread_name_ + ": failed (an exception that is not a std::exception)");
    return;
  }
  ThreadState running = ThreadState::kRunning;
  state_.compare_exchange_strong(running, ThreadState::kStopped);
}

void WorkerThread::fail(const std::string& error) {
  {
    std::lock_guard lock(error_mutex_);
    if (error_.empty()) error_ = error;
  }
  state_.store(ThreadState::kFailed);  // after the text: a reader that sees kFailed finds it
}

void lock_memory() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return;
  const int err = errno;
  throw std::runtime_error("cannot lock memory: mlockall(MCL_CURRENT | MCL_FUTURE) refused (" + error_name(err) +
                           "): needs CAP_IPC_LOCK or LimitMEMLOCK=infinity (RLIMIT_MEMLOCK is " +
                           soft_limit(RLIMIT_MEMLOCK, " KiB", 1024) + ")");
}

}  // namespace noisemon::drivers
