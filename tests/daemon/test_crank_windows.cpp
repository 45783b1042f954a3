// The crank-window levels: each window's A-weighted mean square of what fell in it, against the sine's analytic mean
// square and the A-weighting's table value.
#include "daemon/crank_windows.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace nd = noisemon::daemon;

TEST(CrankWindows, WindowOfCoversTheCycleIn90DegreeSteps) {
  EXPECT_EQ(nd::CrankWindows::window_of(-360.0), 0u);
  EXPECT_EQ(nd::CrankWindows::window_of(-270.001), 0u);
  EXPECT_EQ(nd::CrankWindows::window_of(-270.0), 1u);
  EXPECT_EQ(nd::CrankWindows::window_of(-0.001), 3u);
  EXPECT_EQ(nd::CrankWindows::window_of(0.0), 4u);
  EXPECT_EQ(nd::CrankWindows::window_of(359.999), 7u);
  EXPECT_EQ(nd::CrankWindows::window_of(360.0), 7u);  // clamped
}

// A 1 kHz tone (0 dB A-weighting) in window 2 and a 100 Hz tone (-19.1 dB, and the 200 Hz high-pass: 4th order
// Butterworth, -24.1 dB at half its corner) in window 5 on channel 1, silence on channel 0, each tone begun in the
// window before (the filters settle there): each window reads its own tone, windows without frames NaN.
TEST(CrankWindows, EachWindowReadsWhatFellInIt) {
  constexpr double fs = 40000.0, a = 2.0;
  nd::CrankWindows windows(2, fs);
  auto feed = [&](std::size_t w, double hz, int frames, double& t) {
    for (int i = 0; i < frames; ++i, t += 1.0 / fs) {
      const double frame[2] = {0.0, a * std::sin(2.0 * std::numbers::pi * hz * t)};
      windows.add(w, frame);
    }
  };
  double t = 0.0;
  feed(1, 1000.0, 8000, t);
  feed(2, 1000.0, 8000, t);
  feed(4, 100.0, 8000, t);
  feed(5, 100.0, 8000, t);
  windows.close();
  EXPECT_NEAR(10.0 * std::log10(windows.mean_square(2, 1) / (a * a / 2.0)), 0.0, 0.1);
  const double hundred = 10.0 * std::log10(windows.mean_square(5, 1) / (a * a / 2.0));
  const double highpass_db = -10.0 * std::log10(1.0 + std::pow(200.0 / 100.0, 8.0));
  EXPECT_NEAR(hundred, -19.1 + highpass_db, 0.5);
  EXPECT_EQ(windows.mean_square(2, 0), 0.0);
  EXPECT_TRUE(std::isnan(windows.mean_square(0, 1)));
  EXPECT_TRUE(std::isnan(windows.mean_square(7, 0)));
}
