// SpscRing: capacity rounding, all-or-nothing block writes with overrun counting, wrap-around, the
// consumer's peek/consume/front, and two-thread stress runs where every item is checked against the
// producer's counting sequence.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "dsp/spsc_ring.hpp"
#include "tests/sanitizer.hpp"

namespace noisemon::dsp {
namespace {

TEST(SpscRing, CapacityRoundsUpToAPowerOfTwo) {
  EXPECT_EQ(SpscRing<int>(1).capacity(), 1u);
  EXPECT_EQ(SpscRing<int>(5).capacity(), 8u);
  EXPECT_EQ(SpscRing<int>(8).capacity(), 8u);
  EXPECT_EQ(SpscRing<int>(1000).capacity(), 1024u);
  EXPECT_THROW(SpscRing<int>(0), std::invalid_argument);
  // The rounded capacity is usable in full.
  SpscRing<int> r(5);
  const std::vector<int> eight(8, 1);
  EXPECT_TRUE(r.write(eight.data(), 8));
  EXPECT_EQ(r.size(), 8u);
  EXPECT_DOUBLE_EQ(r.fill_fraction(), 1.0);
}

TEST(SpscRing, BlocksAreWrittenWholeOrDroppedAndCounted) {
  SpscRing<int> r(8);
  const int a[5] = {1, 2, 3, 4, 5}, b[4] = {6, 7, 8, 9}, c[3] = {10, 11, 12};
  EXPECT_TRUE(r.write(a, 5));
  EXPECT_FALSE(r.write(b, 4));  // 3 free: nothing of the block goes in
  EXPECT_EQ(r.size(), 5u);
  EXPECT_EQ(r.overrun_events(), 1u);
  EXPECT_EQ(r.overrun_items(), 4u);
  EXPECT_TRUE(r.write(c, 3));  // exactly fills
  EXPECT_FALSE(r.push(99));
  EXPECT_EQ(r.overrun_events(), 2u);
  EXPECT_EQ(r.overrun_items(), 5u);

  int out[16] = {};
  ASSERT_EQ(r.read(out, 16), 8u);
  const int expected[8] = {1, 2, 3, 4, 5, 10, 11, 12};
  for (int i = 0; i < 8; ++i) EXPECT_EQ(out[i], expected[i]);
  EXPECT_TRUE(r.empty());
  // A block larger than the whole ring can never fit.
  const std::vector<int> big(9, 0);
  EXPECT_FALSE(r.write(big.data(), big.size()));
  EXPECT_EQ(r.overrun_items(), 14u);
  EXPECT_TRUE(r.empty());
}

TEST(SpscRing, WrapsAroundKeepingOrder) {
  SpscRing<std::uint32_t> r(8);
  std::uint32_t next_write = 0, next_read = 0;
  // Block sizes coprime with the capacity walk the indices across the end of storage in every position.
  for (int round = 0; round < 200; ++round) {
    const std::size_t n = 1 + round % 5;
    std::uint32_t block[5];
    for (std::size_t i = 0; i < n; ++i) block[i] = next_write + static_cast<std::uint32_t>(i);
    if (r.write(block, n)) next_write += static_cast<std::uint32_t>(n);
    std::uint32_t out[8];
    const std::size_t got = r.read(out, 1 + round % 3);
    for (std::size_t i = 0; i < got; ++i) ASSERT_EQ(out[i], next_read++);
  }
  std::uint32_t out[8];
  for (std::size_t got; (got = r.read(out, 8)) > 0;)
    for (std::size_t i = 0; i < got; ++i) ASSERT_EQ(out[i], next_read++);
  EXPECT_EQ(next_read, next_write);
  EXPECT_GT(next_write, 8u * 20u);  // went round many times
}

TEST(SpscRing, PeekFrontAndConsume) {
  SpscRing<int> r(4);
  EXPECT_EQ(r.front(), nullptr);
  int out[4] = {};
  EXPECT_EQ(r.peek(out, 4), 0u);
  const int a[3] = {7, 8, 9};
  ASSERT_TRUE(r.write(a, 3));
  // Peek copies without removing.
  ASSERT_EQ(r.peek(out, 2), 2u);
  EXPECT_EQ(out[0], 7);
  EXPECT_EQ(out[1], 8);
  EXPECT_EQ(r.size(), 3u);
  ASSERT_NE(r.front(), nullptr);
  EXPECT_EQ(*r.front(), 7);
  r.consume(1);
  EXPECT_EQ(*r.front(), 8);
  EXPECT_EQ(r.size(), 2u);
  // Wrap: two more go in at storage slots 3 and 0.
  const int b[2] = {10, 11};
  ASSERT_TRUE(r.write(b, 2));
  ASSERT_EQ(r.peek(out, 4), 4u);
  EXPECT_EQ(out[0], 8);
  EXPECT_EQ(out[1], 9);
  EXPECT_EQ(out[2], 10);
  EXPECT_EQ(out[3], 11);
  r.consume(3);
  EXPECT_EQ(*r.front(), 11);
  r.consume(1);
  EXPECT_EQ(r.front(), nullptr);
  EXPECT_TRUE(r.empty());
}

// Producer and consumer threads; the consumer checks every item. Bounded: gives up when no item has arrived for
// kStallLimit, a guard against a hang only. A deadline on the whole run measured the machine instead (a fraction of a
// second idle; beside two diagnoses and a test run at a load of 5, 2^21 items yielding to each other took over 8 s).
const auto kStallLimit = noisemon::test::allowance(std::chrono::seconds(2));

TEST(SpscRing, TwoThreadsRetryingProducerDeliversEveryItemOnceInOrder) {
  constexpr std::uint64_t kItems = 1u << 21;
  SpscRing<std::uint64_t> ring(1024);
  std::atomic<bool> give_up{false};
  auto deadline = std::chrono::steady_clock::now() + kStallLimit;

  std::thread producer([&] {
    std::mt19937 rng(1);
    std::uniform_int_distribution<std::size_t> size(1, 64);
    std::uint64_t block[64];
    for (std::uint64_t next = 0; next < kItems && !give_up.load();) {
      const std::size_t n = std::min<std::uint64_t>(size(rng), kItems - next);
      for (std::size_t i = 0; i < n; ++i) block[i] = next + i;
      if (ring.write(block, n)) {
        next += n;
      } else {
        std::this_thread::yield();  // full: the consumer will make room
      }
    }
  });

  std::mt19937 rng(2);
  std::uniform_int_distribution<std::size_t> size(1, 100);
  std::vector<std::uint64_t> out(100);
  std::uint64_t expected = 0;
  bool in_order = true;
  while (expected < kItems && in_order) {
    if (std::chrono::steady_clock::now() > deadline) break;
    const std::size_t got = ring.read(out.data(), size(rng));
    if (got == 0)
      std::this_thread::yield();
    else
      deadline = std::chrono::steady_clock::now() + kStallLimit;
    for (std::size_t i = 0; i < got; ++i) in_order = in_order && out[i] == expected++;
  }
  give_up = true;
  producer.join();
  EXPECT_TRUE(in_order);
  EXPECT_EQ(expected, kItems) << "stalled";
  EXPECT_TRUE(ring.empty());
}

// Items carry their block's identity so the consumer can see that no block arrives in part.
struct Tagged {
  std::uint64_t block;
  std::uint32_t index;   // position inside the block
  std::uint32_t length;  // block length
};

TEST(SpscRing, TwoThreadsDroppingProducerLosesOnlyWholeCountedBlocks) {
  constexpr std::uint64_t kBlocks = 1000000;
  SpscRing<Tagged> ring(256);
  std::atomic<bool> done{false};
  std::atomic<std::uint64_t> items_written{0};
  std::atomic<bool> size_ok{true};

  std::thread producer([&] {
    std::mt19937 rng(3);
    std::uniform_int_distribution<std::uint32_t> size(1, 48);
    Tagged block[48];
    std::uint64_t items = 0;
    for (std::uint64_t b = 0; b < kBlocks; ++b) {
      const std::uint32_t n = size(rng);
      for (std::uint32_t i = 0; i < n; ++i) block[i] = {b, i, n};
      (void)ring.write(block, n);  // never waits: a full ring drops the block
      items += n;
    }
    items_written = items;
    done = true;
  });
  // A third thread reads the fill level as a status display would.
  std::thread monitor([&] {
    while (!done.load())
      if (ring.size() > ring.capacity()) size_ok = false;
  });

  std::uint64_t received_items = 0, received_blocks = 0;
  std::int64_t last_block = -1;
  Tagged current{0, 0, 0};
  bool whole = true;
  std::vector<Tagged> out(64);
  auto deadline = std::chrono::steady_clock::now() + kStallLimit;
  while (whole && std::chrono::steady_clock::now() < deadline) {
    const bool finished = done.load();
    const std::size_t got = ring.read(out.data(), out.size());
    if (got > 0) deadline = std::chrono::steady_clock::now() + kStallLimit;
    for (std::size_t i = 0; i < got; ++i) {
      const Tagged& t = out[i];
      if (current.index + 1 < current.length) {
        // Inside a block: the next item of the same block must follow.
        whole = whole && t.block == current.block && t.index == current.index + 1;
      } else {
        // A new block starts at its first item, later than the last one.
        whole = whole && t.index == 0 && static_cast<std::int64_t>(t.block) > last_block;
        last_block = static_cast<std::int64_t>(t.block);
        ++received_blocks;
      }
      current = t;
      ++received_items;
    }
    if (finished && got == 0) break;
  }
  done = true;
  producer.join();
  monitor.join();
  EXPECT_TRUE(whole);
  EXPECT_EQ(current.index + 1, current.length) << "last block incomplete";
  EXPECT_EQ(received_blocks + ring.overrun_events(), kBlocks);
  EXPECT_EQ(received_items + ring.overrun_items(), items_written.load());
  EXPECT_TRUE(size_ok.load()) << "size() exceeded the capacity while both sides ran";
}

}  // namespace
}  // namespace noisemon::dsp
