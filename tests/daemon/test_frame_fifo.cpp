// FrameFifo: frames keep their grid index through holds, overflows and restarts; nothing is lost silently.
#include <gtest/gtest.h>

#include <vector>

#include "daemon/frame_fifo.hpp"

using noisemon::daemon::FrameFifo;

namespace {

// n one-channel frames whose value is their grid index.
std::vector<double> frames(std::int64_t first, std::size_t n) {
  std::vector<double> f(n);
  for (std::size_t i = 0; i < n; ++i) f[i] = static_cast<double>(first + static_cast<std::int64_t>(i));
  return f;
}

FrameFifo::Appended add(FrameFifo& fifo, std::int64_t first, std::size_t n) {
  const std::vector<double> f = frames(first, n);
  return fifo.append(first, f.data(), n);
}

}  // namespace

TEST(FrameFifo, KeepsEveryFrameAtItsIndexAndSkipsFramesAlreadyThere) {
  FrameFifo fifo(1, 100);  // rounded up to 128
  EXPECT_EQ(add(fifo, 1000, 50).held, 0u);
  EXPECT_EQ(add(fifo, 1040, 30).dropped, 0u);  // 10 frames again, 20 new
  EXPECT_EQ(fifo.begin_index(), 1000);
  EXPECT_EQ(fifo.end_index(), 1070);
  for (std::int64_t i = 1000; i < 1070; ++i) EXPECT_EQ(fifo.frame(i)[0], static_cast<double>(i));
}

TEST(FrameFifo, AShortGapIsHeldWithTheLastFrame) {
  FrameFifo fifo(1, 128);
  add(fifo, 0, 10);
  const FrameFifo::Appended a = add(fifo, 15, 5);
  EXPECT_EQ(a.held, 5u);
  EXPECT_FALSE(a.restarted);
  for (std::int64_t i = 10; i < 15; ++i) EXPECT_EQ(fifo.frame(i)[0], 9.0);
  EXPECT_EQ(fifo.frame(15)[0], 15.0);
}

TEST(FrameFifo, WhenFullTheOldestFramesArePushedOutAndCounted) {
  FrameFifo fifo(1, 128);
  add(fifo, 0, 100);
  const FrameFifo::Appended a = add(fifo, 100, 60);  // 160 > 128: the 32 oldest go
  EXPECT_EQ(a.dropped, 32u);
  EXPECT_EQ(fifo.begin_index(), 32);
  EXPECT_EQ(fifo.end_index(), 160);
  for (std::int64_t i = 32; i < 160; ++i) EXPECT_EQ(fifo.frame(i)[0], static_cast<double>(i));
  // A held gap that overflows pushes out old frames too.
  const FrameFifo::Appended b = add(fifo, 200, 8);
  EXPECT_EQ(b.held, 40u);
  EXPECT_EQ(b.dropped, 48u);
  EXPECT_EQ(fifo.end_index(), 208);
  EXPECT_EQ(fifo.begin_index(), 208 - 128);
}

TEST(FrameFifo, AGapLongerThanItHoldsRestartsItAtTheNewFrames) {
  FrameFifo fifo(2, 64);
  std::vector<double> two(2 * 10, 1.0);
  fifo.append(0, two.data(), 10);
  const FrameFifo::Appended a = fifo.append(1'000'000, two.data(), 10);
  EXPECT_TRUE(a.restarted);
  EXPECT_EQ(a.held, 0u);
  EXPECT_EQ(a.dropped, 10u);
  EXPECT_EQ(fifo.begin_index(), 1'000'000);
  EXPECT_EQ(fifo.end_index(), 1'000'010);
}

TEST(FrameFifo, MoreNewFramesThanItHoldsKeepsTheNewestAtTheirIndex) {
  FrameFifo fifo(1, 16);
  add(fifo, 0, 4);
  const FrameFifo::Appended a = add(fifo, 4, 40);
  EXPECT_TRUE(a.restarted);
  EXPECT_EQ(a.dropped, 4u + 24u);
  EXPECT_EQ(fifo.begin_index(), 28);
  EXPECT_EQ(fifo.end_index(), 44);
  for (std::int64_t i = 28; i < 44; ++i) EXPECT_EQ(fifo.frame(i)[0], static_cast<double>(i));
}
