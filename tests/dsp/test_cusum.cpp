// The CUSUM's run lengths against the published tables and against a simulation with the standard library's own
// Gaussian generator (nothing of the project's random numbers).
#include "dsp/cusum.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace nd = noisemon::dsp;

namespace {

// Observations until the two-sided CUSUM fires: N(0, 1) before `change`, N(shift, 1) from it on.
struct RunLength {
  std::int64_t length = 0;
  std::int64_t onset = 0;
  int side = 0;
};

RunLength run_until_alarm(nd::Cusum cusum, std::mt19937_64& rng, double shift, std::int64_t change) {
  std::normal_distribution<double> normal(0.0, 1.0);
  for (std::int64_t i = 0;; ++i) {
    const double z = normal(rng) + (i >= change ? shift : 0.0);
    if (const int side = cusum.update(z, i); side != 0) return {i + 1, cusum.onset(), side};
  }
}

}  // namespace

// Montgomery, Introduction to Statistical Quality Control (6th ed.), Table 9.3: the two-sided tabular CUSUM with
// k = 1/2, h = 5 has ARL0 = 465 and ARL 10.4 at a shift of one standard deviation (one side: twice ARL0).
TEST(Cusum, SiegmundApproximationMatchesThePublishedTable) {
  EXPECT_NEAR(nd::cusum_arl(0.5, 5.0) / 2.0, 465.0, 0.02 * 465.0);
  EXPECT_NEAR(nd::cusum_arl(0.5, 5.0, 1.0), 10.4, 0.2);
  EXPECT_NEAR(nd::cusum_arl(0.5, 4.0) / 2.0, 168.0, 0.03 * 168.0);
  EXPECT_NEAR(nd::cusum_arl(0.5, 4.0, 1.0), 8.38, 0.2);
  const double h = nd::cusum_threshold(0.5, 2.0 * 465.0);
  EXPECT_NEAR(h, 5.0, 0.02);
  EXPECT_NEAR(nd::cusum_arl(0.5, h), 930.0, 1e-6 * 930.0);
  EXPECT_EQ(nd::cusum_threshold(3.0, 1.5), 0.0);
  EXPECT_THROW((void)nd::cusum_threshold(0.0, 100.0), std::invalid_argument);
}

// The false-alarm rate the threshold promises is the one a long simulation shows: two sides, each with ARL0 = 400,
// fire on average every 200 observations (3000 runs: the mean is known to +-2 %).
TEST(Cusum, InControlRunLengthIsTheTargetInASimulation) {
  std::mt19937_64 rng(20261129);
  const double k = 0.5, h = nd::cusum_threshold(k, 400.0);
  double total = 0.0;
  int upper = 0;
  const int runs = 3000;
  for (int r = 0; r < runs; ++r) {
    const RunLength run = run_until_alarm(nd::Cusum(k, h), rng, 0.0, INT64_MAX);
    total += static_cast<double>(run.length);
    upper += run.side > 0;
  }
  EXPECT_NEAR(total / runs, 200.0, 0.08 * 200.0);
  EXPECT_NEAR(static_cast<double>(upper) / runs, 0.5, 0.05);
}

// A shift of one standard deviation at observation 300 is found about ARL(1) observations later, on the upper side,
// its onset located at the change within a few observations (median over 400 runs that did not fire before it).
TEST(Cusum, ShiftIsDetectedWithTheExpectedDelayAndItsOnsetLocated) {
  std::mt19937_64 rng(7);
  const double k = 0.5, h = nd::cusum_threshold(k, 20000.0);
  const std::int64_t change = 300;
  std::vector<double> delays, onset_errors;
  while (delays.size() < 400) {
    const RunLength run = run_until_alarm(nd::Cusum(k, h), rng, 1.0, change);
    if (run.length <= change) continue;  // a false alarm before the change
    EXPECT_EQ(run.side, 1);
    delays.push_back(static_cast<double>(run.length - change));
    onset_errors.push_back(std::abs(static_cast<double>(run.onset - change)));
  }
  double mean = 0.0;
  for (const double d : delays) mean += d / static_cast<double>(delays.size());
  // Siegmund's ARL(1) is the zero-start delay; a CUSUM already wandering above zero at the change is a little faster.
  EXPECT_NEAR(mean, nd::cusum_arl(k, h, 1.0), 0.15 * nd::cusum_arl(k, h, 1.0));
  std::nth_element(onset_errors.begin(), onset_errors.begin() + 200, onset_errors.end());
  EXPECT_LE(onset_errors[200], 5.0);
}
