// The pieces of the status message's report latency: the percentiles of a window (against the nearest-rank
// definition worked out by hand) and the wake-up that lets a queued report leave at once.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "daemon/latency_window.hpp"
#include "daemon/wakeup.hpp"

namespace noisemon::daemon {
namespace {

using Clock = std::chrono::steady_clock;

TEST(LatencyWindow, NearestRankPercentilesOfAShuffledWindow) {
  // 1..200 ms in a scrambled order: the nearest-rank p50 is the 100th smallest (100), p99 the 198th (198).
  LatencyWindow w;
  for (int i = 0; i < 200; ++i) w.add(static_cast<double>((i * 37) % 200 + 1));
  EXPECT_DOUBLE_EQ(w.quantile(0.5), 100.0);
  EXPECT_DOUBLE_EQ(w.quantile(0.99), 198.0);
  EXPECT_DOUBLE_EQ(w.quantile(1.0), 200.0);
  EXPECT_DOUBLE_EQ(w.max(), 200.0);
}

TEST(LatencyWindow, EmptyIsZeroAndClearStartsAfresh) {
  LatencyWindow w;
  EXPECT_EQ(w.quantile(0.5), 0.0);
  w.add(3.0);
  EXPECT_DOUBLE_EQ(w.quantile(0.5), 3.0);
  EXPECT_DOUBLE_EQ(w.quantile(0.99), 3.0);
  w.clear();
  EXPECT_EQ(w.quantile(0.99), 0.0);
  EXPECT_EQ(w.max(), 0.0);
}

TEST(LatencyWindow, BeyondItsCapacityOnlyTheMaximumCounts) {
  LatencyWindow w(4);
  for (double v : {1.0, 2.0, 3.0, 4.0, 50.0}) w.add(v);
  EXPECT_DOUBLE_EQ(w.quantile(1.0), 4.0);  // the fifth value is not kept
  EXPECT_DOUBLE_EQ(w.max(), 50.0);
}

TEST(Wakeup, ANotifyEndsTheWaitLongBeforeItsTimeout) {
  Wakeup wakeup;
  std::thread notifier([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    wakeup.notify();
  });
  const auto start = Clock::now();
  wakeup.wait_for(std::chrono::seconds(20));
  const double waited_s = std::chrono::duration<double>(Clock::now() - start).count();
  notifier.join();
  EXPECT_LT(waited_s, 10.0);  // the timeout is 20 s: only the notify can have ended it
}

TEST(Wakeup, ANotifyBeforeTheWaitIsNotLostAndTheTimeoutEndsAnIdleWait) {
  Wakeup wakeup;
  wakeup.notify();
  const auto start = Clock::now();
  wakeup.wait_for(std::chrono::seconds(20));  // returns at once: the notify came first
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - start).count(), 10.0);
  const auto idle = Clock::now();
  wakeup.wait_for(std::chrono::milliseconds(30));  // nothing to wake it: the timeout does
  EXPECT_GE(std::chrono::duration<double>(Clock::now() - idle).count(), 0.025);
}

}  // namespace
}  // namespace noisemon::daemon
