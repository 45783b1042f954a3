// Single-producer single-consumer lock-free ring buffer.
//
// One producer thread calls write(); one consumer thread calls read()/peek()/consume().
// Storage is preallocated at construction; neither side allocates, locks or blocks afterwards.
// The producer never waits: a block that does not fit is dropped whole (so frame alignment is kept)
// and counted as an overrun. Head and tail live on separate cache lines, each side keeps a cached
// copy of the other side's index so the common case touches only its own line (after rigtorp's SPSCQueue).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <stdexcept>
#include <type_traits>

namespace noisemon::dsp {

inline constexpr std::size_t kCacheLine = 64;

template <class T>
class SpscRing {
  static_assert(std::is_trivially_copyable_v<T>, "SpscRing holds trivially copyable items");

 public:
  // capacity: the number of items the ring holds at once (rounded up to a power of two).
  explicit SpscRing(std::size_t capacity) {
    if (capacity == 0) throw std::invalid_argument("SpscRing: capacity must be positive");
    std::size_t cap = 1;
    while (cap < capacity) cap <<= 1;
    capacity_ = cap;
    mask_ = cap - 1;
    // Not zero-filled: a slot is written before it is read, and a 5 s ring of 32 KiB blocks is hundreds of MB the
    // daemon would write at start-up (seconds on a busy machine). Its pages come in as the ring first goes round,
    // or all at once under mlockall (the daemon's lock_memory), where a page fault must not meet the real-time path.
    slots_ = std::make_unique_for_overwrite<T[]>(cap);
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  [[nodiscard]] std::size_t capacity() const noexcept { return capacity_; }

  // Producer: writes all n items or none. Returns false (and counts an overrun of n items) when the
  // ring lacks room for the whole block: a caller that drops data says so with (void).
  [[nodiscard]] bool write(const T* items, std::size_t n) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (capacity_ - (head - tail_cache_) < n) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (capacity_ - (head - tail_cache_) < n) {
        overrun_events_.fetch_add(1, std::memory_order_relaxed);
        overrun_items_.fetch_add(n, std::memory_order_relaxed);
        return false;
      }
    }
    const std::size_t start = head & mask_;
    const std::size_t first = n < capacity_ - start ? n : capacity_ - start;
    copy(items, slots_.get() + start, first);
    copy(items + first, slots_.get(), n - first);
    head_.store(head + n, std::memory_order_release);
    return true;
  }
  [[nodiscard]] bool push(const T& item) noexcept { return write(&item, 1); }

  // Consumer: copies up to max items out, returns how many.
  [[nodiscard]] std::size_t read(T* out, std::size_t max) noexcept {
    const std::size_t n = peek(out, max);
    consume(n);
    return n;
  }
  // Consumer: copies up to max items without removing them.
  [[nodiscard]] std::size_t peek(T* out, std::size_t max) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    std::size_t avail = head_cache_ - tail;
    if (avail < max) {
      head_cache_ = head_.load(std::memory_order_acquire);
      avail = head_cache_ - tail;
    }
    const std::size_t n = avail < max ? avail : max;
    const std::size_t start = tail & mask_;
    const std::size_t first = n < capacity_ - start ? n : capacity_ - start;
    copy(slots_.get() + start, out, first);
    copy(slots_.get(), out + first, n - first);
    return n;
  }
  // Consumer: pointer to the next item without copying (nullptr when empty). Valid until consume().
  [[nodiscard]] const T* front() noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (head_cache_ == tail) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (head_cache_ == tail) return nullptr;
    }
    return &slots_[tail & mask_];
  }
  void consume(std::size_t n) noexcept {
    tail_.store(tail_.load(std::memory_order_relaxed) + n, std::memory_order_release);
  }

  // Either side (approximate while the other side runs).
  std::size_t size() const noexcept {
    // Tail first: the head read afterwards is never behind it (reading head first lets the consumer pass
    // the stale head, and the unsigned difference wraps to ~2^64). Both sides may move in between, so clamp.
    const std::size_t tail = tail_.load(std::memory_order_acquire);
    const std::size_t used = head_.load(std::memory_order_acquire) - tail;
    return used < capacity_ ? used : capacity_;
  }
  bool empty() const noexcept { return size() == 0; }
  double fill_fraction() const noexcept { return static_cast<double>(size()) / static_cast<double>(capacity_); }
  std::uint64_t overrun_events() const noexcept { return overrun_events_.load(std::memory_order_relaxed); }
  std::uint64_t overrun_items() const noexcept { return overrun_items_.load(std::memory_order_relaxed); }

 private:
  static void copy(const T* from, T* to, std::size_t n) noexcept {
    for (std::size_t i = 0; i < n; ++i) to[i] = from[i];
  }

  std::size_t capacity_ = 0;
  std::size_t mask_ = 0;
  std::unique_ptr<T[]> slots_;

  alignas(kCacheLine) std::atomic<std::size_t> head_{0};  // written by the producer
  std::size_t tail_cache_ = 0;                            // producer's view of tail_
  std::atomic<std::uint64_t> overrun_events_{0};
  std::atomic<std::uint64_t> overrun_items_{0};
  alignas(kCacheLine) std::atomic<std::size_t> tail_{0};  // written by the consumer
  std::size_t head_cache_ = 0;                            // consumer's view of head_
  char pad_[kCacheLine - sizeof(std::atomic<std::size_t>) - sizeof(std::size_t)];
};

}  // namespace noisemon::dsp
