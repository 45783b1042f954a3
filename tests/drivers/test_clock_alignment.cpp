// Aligning a front-end on its own crystal to the encoder's clock (drivers/aligned_stream.hpp and its parts), on a card
// written from the physics alone (tests/support/drifting_card.hpp): its crystal +80 or -50 ppm off, a jittered
// clock, a sync pulse once a revolution of an engine whose speed wanders, host readings late by up to a period.
// The truth is the card's own instants: the output's frame k must be the microphone's sound at k / 40 kHz.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "drivers/aligned_stream.hpp"
#include "drivers/clock_tracker.hpp"
#include "drivers/crank_reference.hpp"
#include "drivers/sync_pulse.hpp"
#include "tests/support/alignment_run.hpp"
#include "tests/support/drifting_card.hpp"

namespace nd = noisemon::drivers;
using noisemon::test::AlignmentRun;
using noisemon::test::DriftingCard;
using noisemon::test::DriftingCardSpec;
using noisemon::test::run_card;

namespace {

TEST(ClockTracker, FollowsACrystalOffItsRateAndItsStatedUncertaintyHoldsTheError) {
  nd::ClockTracker::Options o;
  o.nominal_rate_hz = 48000.0;
  nd::ClockTracker tracker(o, 0.0);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1e-6);
  const double period = 1.0 / (48000.0 * (1.0 + 80e-6));
  int within_2_sigma = 0, checked = 0;
  for (int i = 1; i <= 3000; ++i) {  // one observation every 960 scans (20 ms), for 60 s
    const double q = 960.0 * i;
    const double truth = q * period;
    if (i > 100) {  // the prediction before each observation, against the truth
      const double error = tracker.time_at(q) - truth;
      within_2_sigma += std::abs(error) < 2.0 * tracker.sigma_at(q);
      ++checked;
    }
    EXPECT_TRUE(tracker.observe(q, truth + noise(rng), 1e-6));
  }
  EXPECT_NEAR(tracker.ppm(), 80.0, 0.05);
  EXPECT_LT(tracker.ppm_sigma(), 0.05);
  EXPECT_GT(within_2_sigma, 0.9 * checked);  // a Gaussian's 2 sigma hold 95 %
  EXPECT_LT(tracker.sigma_at(960.0 * 3000), 1e-6);
}

TEST(ClockTracker, AnOutlierIsRejectedAndAnEarlierPositionRefused) {
  nd::ClockTracker::Options o;
  nd::ClockTracker tracker(o, 0.0);
  for (int i = 1; i <= 200; ++i) ASSERT_TRUE(tracker.observe(960.0 * i, 960.0 * i / 48000.0, 1e-6));
  EXPECT_FALSE(tracker.observe(960.0 * 201, 960.0 * 201 / 48000.0 + 1e-3, 1e-6));  // 1 ms off: a false pulse
  EXPECT_FALSE(tracker.observe(960.0 * 100, 960.0 * 100 / 48000.0, 1e-6));
  EXPECT_EQ(tracker.rejected(), 2u);
  EXPECT_NEAR(tracker.time_at(960.0 * 202), 960.0 * 202 / 48000.0, 1e-7);
}

// Band-limited pulses (erf edges) with noise and the ringing of a converter's filter after each edge.
TEST(SyncPulseDetector, FindsEachRisingEdgeBetweenScansAndIgnoresRingingAndADeadInput) {
  nd::SyncPulseDetector detector(0.05, 96000.0);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, 0.003);
  const double rate = 48000.0, rise = 8e-6;
  std::vector<double> edges_true, edges_found;
  for (int p = 0; p < 50; ++p) edges_true.push_back(0.01 + p * 0.0213 + 1.7e-6 * p);
  for (std::int64_t j = 0; j < static_cast<std::int64_t>(1.1 * rate); ++j) {
    const double t = j / rate;
    double v = -0.4;
    for (double e : edges_true) {
      v += 0.4 * (std::erf((t - e) / rise) - std::erf((t - e - 0.002) / rise));
      if (t > e) v += 0.06 * std::exp(-(t - e) / 1e-4) * std::sin(2 * M_PI * 21000.0 * (t - e));  // Gibbs' ringing
    }
    double q = 0.0;
    if (detector.add(v + noise(rng), j, &q)) edges_found.push_back(q / rate);
  }
  ASSERT_EQ(edges_found.size(),
            edges_true.size() - 1);  // the first pulse only sets the levels; each edge within a fifth of a scan
  for (std::size_t i = 0; i < edges_found.size(); ++i)
    EXPECT_NEAR(edges_found[i], edges_true[i + 1], 4.2e-6) << "edge " << i + 1;

  nd::SyncPulseDetector dead(0.05, 96000.0);
  double q = 0.0;
  int found = 0;
  for (std::int64_t j = 0; j < 48000; ++j) found += dead.add(noise(rng), j, &q);
  EXPECT_EQ(found, 0);
}

TEST(CrankReference, PostsTheInstantsTheCrankPassesItsAngleEachRevolution) {
  nd::CrankReference reference(37.0);
  const double deg_per_frame = 3000.0 * 6.0 / 40000.0;  // 3000 rpm
  nd::SampleBlock block{};
  block.channels = nd::kPressureStreamChannels;
  std::int64_t index = 0;
  for (int b = 0; b < 40; ++b) {
    block.first_index = index;
    block.frames = nd::SampleBlock::kMaxFrames;
    for (std::uint32_t f = 0; f < block.frames; ++f, ++index) {
      const double a = std::fmod(-200.0 + deg_per_frame * static_cast<double>(index) + 360.0, 720.0) - 360.0;
      block.data[f * block.channels + nd::kCrankChannel] = (index >= 5000 && index < 5100) ? NAN : a;
    }
    reference.add_crank(block);
  }
  // 37 deg is passed at frames (37 + 200) / 0.45 + k * 800: each revolution 20 ms.
  for (double frame = 237.0 / deg_per_frame; frame < index - 1; frame += 800.0) {
    const nd::CrankReference::Match m = reference.nearest(frame / 40000.0);
    if (frame > 4990 && frame < 5110) continue;  // the crank was not known there
    EXPECT_NEAR(m.instant_s, frame / 40000.0, 1e-9) << "frame " << frame;
    EXPECT_NEAR(m.revolution_s, 0.02, 1e-9);
  }
}

TEST(AlignedStream, WithTheSyncPulseTheStreamStaysWithinASmallFractionOfASampleAtPlus80AndMinus50Ppm) {
  for (double ppm : {80.0, -50.0}) {
    DriftingCardSpec spec;
    spec.ppm = ppm;
    const AlignmentRun run = run_card(spec, true, 30.0);
    EXPECT_TRUE(run.synced) << ppm;
    EXPECT_LT(run.worst_error_s, 0.1 / 40000.0) << ppm << " ppm: " << run.worst_error_s * 1e6 << " us";
    EXPECT_NEAR(run.ppm, ppm, 0.5);
    EXPECT_EQ(run.sync_losses, 0u);
    EXPECT_EQ(run.realignments, 1u) << "the lock, once";  // the host's 3 ms put right once
    EXPECT_GT(run.frames, 28u * 40000u);
  }
}

TEST(AlignedStream, WithoutASyncPulseTheErrorStaysWithinTheStatedUncertainty) {
  DriftingCardSpec spec;
  spec.ppm = 80.0;
  const AlignmentRun run = run_card(spec, false, 40.0);
  EXPECT_FALSE(run.synced);
  EXPECT_LT(std::abs(run.ppm - 80.0), 4.0 * run.ppm_sigma) << run.ppm << " +- " << run.ppm_sigma;
  EXPECT_LT(run.ppm_sigma, 10.0);
  EXPECT_LT(run.worst_error_over_stated, 3.0) << "worst " << run.worst_error_s * 1e6 << " us";
  EXPECT_EQ(run.realignments, 0u);
}

TEST(AlignedStream, ALostSyncPulseFallsBackToTheHostClockFlaggedAndStillWithinItsUncertainty) {
  DriftingCardSpec spec;
  spec.ppm = -50.0;
  const AlignmentRun run = run_card(spec, true, 30.0, 15.0);
  EXPECT_FALSE(run.synced);
  EXPECT_EQ(run.sync_losses, 1u);
  EXPECT_LT(run.worst_error_over_stated, 3.0) << "worst " << run.worst_error_s * 1e6 << " us";
}

TEST(AlignedStream, ANoisySyncChannelDoesNotMoveTheStream) {
  DriftingCardSpec spec;
  spec.sync_noise = 0.12;  // spikes and hiss on the pulse line: false edges between the pulses
  const AlignmentRun run = run_card(spec, true, 30.0);
  EXPECT_LT(run.worst_error_s, 0.25 / 40000.0) << run.worst_error_s * 1e6 << " us";
}

}  // namespace
