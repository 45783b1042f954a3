// Throughput of SpscRing between two threads, side by side with a mutex + std::deque queue doing the same
// job (bounded, whole-block writes, producer never blocks on a full queue) as the baseline.
// Items are doubles (written in blocks) and 256-frame sample blocks (drivers::SampleBlock, ~32 KiB each).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <mutex>
#include <thread>
#include <vector>

#include "drivers/source.hpp"
#include "dsp/spsc_ring.hpp"

namespace {

using noisemon::drivers::SampleBlock;
using noisemon::dsp::SpscRing;

// The baseline: same interface, one lock around a deque.
template <class T>
class MutexDequeQueue {
 public:
  explicit MutexDequeQueue(std::size_t capacity) : capacity_(capacity) {}
  bool write(const T* items, std::size_t n) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (capacity_ - queue_.size() < n) return false;
    queue_.insert(queue_.end(), items, items + n);
    return true;
  }
  std::size_t read(T* out, std::size_t max) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::size_t n = std::min(max, queue_.size());
    std::copy_n(queue_.begin(), n, out);
    queue_.erase(queue_.begin(), queue_.begin() + static_cast<std::ptrdiff_t>(n));
    return n;
  }

 private:
  std::size_t capacity_;
  std::mutex mutex_;
  std::deque<T> queue_;
};

// Moves `items` items from a producer thread (writing `block` at a time, retrying when full) to this thread.
template <class Queue, class T>
void transfer(Queue& queue, std::size_t items, std::size_t block, std::vector<T>& in, std::vector<T>& out) {
  std::thread producer([&] {
    for (std::size_t sent = 0; sent < items;) {
      const std::size_t n = std::min(block, items - sent);
      if (queue.write(in.data(), n)) {
        sent += n;
      } else {
        std::this_thread::yield();
      }
    }
  });
  for (std::size_t received = 0; received < items;) {
    const std::size_t n = queue.read(out.data(), out.size());
    if (n == 0) std::this_thread::yield();
    benchmark::DoNotOptimize(out.data());
    received += n;
  }
  producer.join();
}

template <class Queue, class T>
void run(benchmark::State& state, std::size_t capacity, std::size_t items) {
  const auto block = static_cast<std::size_t>(state.range(0));
  std::vector<T> in(block), out(block);
  for (auto _ : state) {
    Queue queue(capacity);
    transfer(queue, items, block, in, out);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * items));
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * items * sizeof(T)));
}

constexpr std::size_t kDoubles = 1 << 22;  // per iteration
constexpr std::size_t kBlocks = 1 << 12;

void BM_SpscRing_double(benchmark::State& s) { run<SpscRing<double>, double>(s, 1 << 14, kDoubles); }
void BM_MutexDeque_double(benchmark::State& s) { run<MutexDequeQueue<double>, double>(s, 1 << 14, kDoubles); }
void BM_SpscRing_SampleBlock(benchmark::State& s) { run<SpscRing<SampleBlock>, SampleBlock>(s, 16, kBlocks); }
void BM_MutexDeque_SampleBlock(benchmark::State& s) { run<MutexDequeQueue<SampleBlock>, SampleBlock>(s, 16, kBlocks); }

// Argument: items per write (and per read).
BENCHMARK(BM_SpscRing_double)->Arg(1)->Arg(64)->Arg(256)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MutexDeque_double)->Arg(1)->Arg(64)->Arg(256)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SpscRing_SampleBlock)->Arg(1)->UseRealTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MutexDeque_SampleBlock)->Arg(1)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
