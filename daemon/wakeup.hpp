// One thread waking another without a lock: the processing thread (real time) tells the publishing thread a
// report is queued, so the report leaves at once instead of at the publisher's next poll. A Linux futex on a
// counter: notify() is one atomic add and one system call, never blocks and never allocates.
#pragma once

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <ctime>

namespace noisemon::daemon {

class Wakeup {
 public:
  // Any thread.
  void notify() noexcept {
    count_.fetch_add(1, std::memory_order_release);
    syscall(SYS_futex, &count_, FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
  }
  // The one waiting thread: returns after a notify() since the previous wait returned, or after `timeout`.
  void wait_for(std::chrono::microseconds timeout) noexcept {
    const std::uint32_t now = count_.load(std::memory_order_acquire);
    if (now != seen_) {
      seen_ = now;
      return;
    }
    const timespec ts{static_cast<std::time_t>(timeout.count() / 1000000),
                      static_cast<long>(timeout.count() % 1000000) * 1000};
    syscall(SYS_futex, &count_, FUTEX_WAIT_PRIVATE, seen_, &ts, nullptr, 0);
    seen_ = count_.load(std::memory_order_acquire);
  }

 private:
  static_assert(sizeof(std::atomic<std::uint32_t>) == 4, "a futex is a 32-bit word");
  std::atomic<std::uint32_t> count_{0};
  std::uint32_t seen_ = 0;  // the waiter's
};

}  // namespace noisemon::daemon
