// Encoder faults through EdgeStreamAssembler (index_resets_counter): a crank at constant speed, a 3600-count
// encoder whose counter the test models itself (reset to 0 at the edge of the index, 50 degrees after firing
// TDC; a 32-bit register counting up, or down in a direction fault) and a pressure trace with a clear
// compression peak at firing TDC (a 50 bar Gaussian on 1 bar, period 720 degrees) for the phase voting. Faults
// are injected into the counter (edges not counted, spurious counts, indices that do not reset it, counting
// down). Every 40 kHz frame is checked against the analytic crank angle and pressure at its instant: the crank
// angle is NaN exactly where the test expects it (the revolutions a fault touched, between analytic index
// instants, within two frames) and right everywhere else; the pressure is right everywhere (NaN crank or not).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "drivers/comedi/comedi_streams.hpp"
#include "dsp/math_constants.hpp"

namespace nd = noisemon::drivers;

namespace {

constexpr std::uint32_t kCpr = 3600;
constexpr double kResolution = 360.0 / kCpr;  // degrees per edge
constexpr double kOmega = 7200.0;             // deg/s (1200 rpm)
constexpr double kIndexDeg = 50.0;            // the index, degrees after firing TDC
constexpr double kTheta0 = -250.0;            // crank angle at the acquisition origin (t = 0)
constexpr double kTimebase = 80e6;
constexpr std::int64_t kEpoch = 1'700'000'000'000'000;
constexpr double kFrame = 1.0 / 40000.0;
using noisemon::kInf;

double theta_at(double t) { return kTheta0 + kOmega * t; }
double time_at(double theta) { return (theta - kTheta0) / kOmega; }
double wrap720(double a) { return a - 720.0 * std::floor((a + 360.0) / 720.0); }
double pressure_pa(double theta) {
  const double a = wrap720(theta) / 30.0;
  return 1e5 + 50e5 * std::exp(-a * a);
}
std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0 && (a < 0) != (b < 0)) ? 1 : 0); }

// True edge m is at kIndexDeg + m * kResolution: revolution r holds edges r * kCpr .. (r + 1) * kCpr - 1 and
// starts at its index, at index_time(r).
double edge_theta(std::int64_t m) { return kIndexDeg + kResolution * static_cast<double>(m); }
double index_time(std::int64_t r) { return time_at(kIndexDeg + 360.0 * static_cast<double>(r)); }

struct Faults {
  std::set<std::int64_t> missing;                 // edges the counter never counts (no scan either)
  std::set<std::int64_t> extra;                   // a spurious count (and scan) half-way after each of these edges
  std::set<std::int64_t> lost;                    // revolutions whose index does not reset the counter
  std::int64_t reverse_from = 0, reverse_to = 0;  // edges [from, to) count down
  double pause_after_s = kInf, pause_s = 0.0;     // the crank stands still this long once past this instant
};

nd::comedi::EdgeStreamConfig config(bool checked, std::uint32_t counts_per_edge) {
  nd::comedi::EdgeStreamConfig c;
  c.stream_channels = {3};
  c.pressure = {0, 0};
  c.position = {0, 1};
  c.timestamp = {0, 2};
  c.counts_per_rev = kCpr * counts_per_edge;
  c.counts_per_edge = counts_per_edge;
  c.index_angle_deg = kIndexDeg;
  c.timebase_hz = kTimebase;
  c.timestamp_bits = 32;
  c.timestamp_mode = nd::comedi::TimestampMode::kAbsolute;
  c.phase = nd::comedi::PhaseSource::kPressure;
  c.max_scan_skew = 1;
  c.index_resets_counter = checked;
  return c;
}

struct Frame {
  double p, crank;
};

struct Outcome {
  std::map<std::int64_t, Frame> frames;
  nd::comedi::EdgeStreamCounters counters;
  std::uint64_t reverse_steps = 0;   // down-counts the test's counter made (an index resets instead)
  std::int64_t last_revolution = 0;  // revolution the last edge belongs to
};

// The edges of `duration_s` of crank rotation through the modelled counter into an assembler.
// counts_per_edge: the counter counts that many a clocking edge (x4 quadrature decoding, scans on one edge).
Outcome simulate(const Faults& f, double duration_s, bool checked = true, std::uint32_t counts_per_edge = 1) {
  nd::comedi::EdgeStreamAssembler a(config(checked, counts_per_edge), kEpoch);
  nd::BlockRing ring(256);
  Outcome out;
  auto drain = [&] {
    while (const nd::SampleBlock* b = ring.front()) {
      for (std::uint32_t i = 0; i < b->frames; ++i)
        out.frames[b->first_index + i] = {b->data[2 * i], b->data[2 * i + 1]};
      ring.consume(1);
    }
  };
  auto scan = [&](double t, double theta, std::uint32_t counter) {
    const double ticks = static_cast<double>(static_cast<std::uint64_t>(std::llround(t * kTimebase)) & 0xffffffffULL);
    const double values[3] = {pressure_pa(theta), static_cast<double>(counter), ticks};
    a.add_scan(0, values, ring);
  };
  auto m = static_cast<std::int64_t>(std::ceil((theta_at(0.0) - kIndexDeg) / kResolution));
  // The card started earlier: the counter counts from the last index.
  auto counter = static_cast<std::uint32_t>((m - 1 - floor_div(m - 1, kCpr) * kCpr) * counts_per_edge);
  const double pause_theta = theta_at(f.pause_after_s);
  for (std::uint64_t n = 0;; ++m) {
    const double theta = edge_theta(m);
    double t = time_at(theta);
    if (theta > pause_theta) t += f.pause_s;
    if (t > duration_s) break;
    out.last_revolution = floor_div(m, kCpr);
    if (f.missing.count(m)) continue;
    const bool down = m >= f.reverse_from && m < f.reverse_to;
    if (m % kCpr == 0 && !f.lost.count(m / kCpr)) {
      counter = 0;  // the index resets the counter at its edge
    } else {
      counter += down ? 0u - counts_per_edge : counts_per_edge;  // counting down wraps like the card's register
      out.reverse_steps += down ? 1 : 0;
    }
    scan(t, theta, counter);
    if (f.extra.count(m)) scan(t + 0.5 * kResolution / kOmega, theta + 0.5 * kResolution, counter += counts_per_edge);
    if (++n % 4096 == 0) {
      a.deliver(ring, false);
      drain();
    }
  }
  a.deliver(ring, true);
  drain();
  out.counters = a.counters();
  return out;
}

double angle_error(double a, double b) { return std::remainder(a - b, 720.0); }

// Frame times (s) of the NaN-crank stretches.
std::vector<std::pair<double, double>> nan_spans(const Outcome& r) {
  std::vector<std::pair<double, double>> spans;
  std::int64_t previous = std::numeric_limits<std::int64_t>::min();
  for (const auto& [k, v] : r.frames) {
    if (!std::isnan(v.crank)) continue;
    const double t = static_cast<double>(k) * kFrame;
    if (k == previous + 1) {
      spans.back().second = t;
    } else {
      spans.emplace_back(t, t);
    }
    previous = k;
  }
  return spans;
}

// Every frame: NaN crank exactly in the expected stretches (their ends within two frames), the analytic angle
// everywhere else; the pressure right in every frame. Returns the largest angle error of the valid frames.
double check(const Outcome& r, const std::vector<std::pair<double, double>>& expected_nan, double p_tol_pa = 50.0) {
  const auto spans = nan_spans(r);
  EXPECT_EQ(spans.size(), expected_nan.size());
  for (std::size_t i = 0; i < std::min(spans.size(), expected_nan.size()); ++i) {
    EXPECT_NEAR(spans[i].first, expected_nan[i].first, 2 * kFrame) << "NaN stretch " << i << " starts";
    if (std::isfinite(expected_nan[i].second)) {
      EXPECT_NEAR(spans[i].second, expected_nan[i].second, 2 * kFrame) << "NaN stretch " << i << " ends";
    }
  }
  double max_err = 0.0, max_p_err = 0.0;
  std::size_t valid = 0;
  for (const auto& [k, v] : r.frames) {
    const double theta = theta_at(static_cast<double>(k) * kFrame);
    max_p_err = std::max(max_p_err, std::abs(v.p - pressure_pa(theta)));
    if (std::isnan(v.crank)) continue;
    EXPECT_GE(v.crank, -360.0);
    EXPECT_LT(v.crank, 360.0);
    max_err = std::max(max_err, std::abs(angle_error(v.crank, wrap720(theta))));
    ++valid;
  }
  EXPECT_GT(valid, 0u);
  EXPECT_LT(max_err, 1e-3) << "a wrong crank angle was published as right";
  EXPECT_LT(max_p_err, p_tol_pa);
  std::printf("%zu frames, %zu with crank angle (max error %.2e deg), pressure max error %.0f Pa, NaN stretches:",
              r.frames.size(), valid, max_err, max_p_err);
  for (const auto& [a, b] : spans) std::printf(" [%.2f, %.2f] ms", 1e3 * a, 1e3 * b);
  std::printf("\n");
  return max_err;
}

// Revolutions whose closing index the assembler sees: from the first full one to the last closed one.
std::uint64_t closed_revolutions(const Outcome& r, std::size_t indices_missed = 0) {
  return static_cast<std::uint64_t>(r.last_revolution) - indices_missed;  // revolutions 0 .. last - 1
}

constexpr double kDuration = 1.0;  // s: 20 revolutions

}  // namespace

TEST(EdgeStreamFaults, CleanRunIsExactAfterLockWithoutNaN) {
  const Outcome r = simulate(Faults{}, kDuration);
  ASSERT_FALSE(r.frames.empty());
  // Locked at the second TDC window (gas-exchange TDC + 30 deg, 640 deg after the start); frames from there.
  const double first_t = static_cast<double>(r.frames.begin()->first) * kFrame;
  EXPECT_NEAR(first_t, time_at(390.0), 0.5e-3);
  // The revolution still open at the stop goes out unconfirmed: NaN from its index on.
  check(r, {{index_time(r.last_revolution), kInf}});
  // Contiguous.
  EXPECT_EQ(static_cast<std::int64_t>(r.frames.size()), r.frames.rbegin()->first - r.frames.begin()->first + 1);
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r));
  EXPECT_EQ(r.counters.revolutions_flagged, 0u);
  EXPECT_EQ(r.counters.missing_or_extra, 0u);
  EXPECT_EQ(r.counters.lost_index, 0u);
  EXPECT_EQ(r.counters.reverse_steps, 0u);
  EXPECT_EQ(r.counters.encoder_errors, 0u);
  EXPECT_EQ(r.counters.phase_corrections, 0u);
}

TEST(EdgeStreamFaults, UncheckedModeGivesTheSameFramesWithoutTheLag) {
  const Outcome checked = simulate(Faults{}, kDuration, true);
  const Outcome plain = simulate(Faults{}, kDuration, false);
  EXPECT_EQ(plain.counters.revolutions_checked, 0u);
  EXPECT_TRUE(nan_spans(plain).empty());
  std::size_t common = 0;
  for (const auto& [k, v] : checked.frames) {
    const auto it = plain.frames.find(k);
    if (std::isnan(v.crank) || it == plain.frames.end()) continue;
    EXPECT_EQ(v.p, it->second.p) << k;
    EXPECT_EQ(v.crank, it->second.crank) << k;
    ++common;
  }
  EXPECT_GT(common, static_cast<std::size_t>(0.8 * kDuration * 40000));
}

TEST(EdgeStreamFaults, MissingEdgesMakeExactlyTheirRevolutionNaN) {
  constexpr std::int64_t kRev = 8;
  Faults f;
  for (std::int64_t e : {1000, 2000, 3000}) f.missing.insert(kRev * kCpr + e);
  const Outcome r = simulate(f, kDuration);
  check(r, {{index_time(kRev), index_time(kRev + 1)}, {index_time(r.last_revolution), kInf}});
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r));
  EXPECT_EQ(r.counters.revolutions_flagged, 1u);
  EXPECT_EQ(r.counters.missing_or_extra, 1u);
  EXPECT_EQ(r.counters.lost_index, 0u);
  EXPECT_EQ(r.counters.reverse_steps, 0u);
  EXPECT_EQ(r.counters.phase_corrections, 0u);
}

TEST(EdgeStreamFaults, ExtraEdgesMakeExactlyTheirRevolutionNaN) {
  constexpr std::int64_t kRev = 8;
  Faults f;
  for (std::int64_t e : {1000, 2000, 3000}) f.extra.insert(kRev * kCpr + e);
  const Outcome r = simulate(f, kDuration);
  check(r, {{index_time(kRev), index_time(kRev + 1)}, {index_time(r.last_revolution), kInf}});
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r));
  EXPECT_EQ(r.counters.revolutions_flagged, 1u);
  EXPECT_EQ(r.counters.missing_or_extra, 1u);
  EXPECT_EQ(r.counters.lost_index, 0u);
  EXPECT_EQ(r.counters.reverse_steps, 0u);
}

TEST(EdgeStreamFaults, LostIndexIsNaNUntilResynchronised) {
  // The indices opening revolutions 8 and 9 do not reset the counter: it runs on to 3 * 3600 - 1.
  constexpr std::int64_t kRev = 8;
  Faults f;
  f.lost = {kRev, kRev + 1};
  const Outcome r = simulate(f, kDuration);
  // Revolution 7 is never confirmed (its closing index is the first one lost); the index opening revolution 10
  // brings the count back and the phase is decided again within revolution 11, which releases 10 with angles.
  check(r, {{index_time(kRev - 1), index_time(kRev + 2)}, {index_time(r.last_revolution), kInf}});
  EXPECT_EQ(r.counters.lost_index, 2u);
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r, 2));
  EXPECT_EQ(r.counters.revolutions_flagged, 1u);  // revolution 7 to the index of 10, as one
  EXPECT_EQ(r.counters.missing_or_extra, 0u);
  EXPECT_EQ(r.counters.reverse_steps, 0u);
}

TEST(EdgeStreamFaults, CountingDownIsNaNThenValidWithTheRightPhase) {
  // 300 edges counted down across the index of revolution 8 (the register wraps below 0 to 2^32 - 1), then
  // counting up again from there: the raw position is garbage until the index of revolution 9.
  constexpr std::int64_t kRev = 8;
  Faults f;
  f.reverse_from = kRev * kCpr - 150;
  f.reverse_to = kRev * kCpr + 150;
  const Outcome r = simulate(f, kDuration);
  check(r, {{index_time(kRev - 1), index_time(kRev + 1)}, {index_time(r.last_revolution), kInf}});
  const double resumed = time_at(edge_theta(f.reverse_to));
  EXPECT_LE((index_time(kRev + 1) - resumed) * kOmega, 2 * 720.0);
  EXPECT_EQ(r.reverse_steps, 299u);  // the index edge inside the fault resets instead
  EXPECT_EQ(r.counters.reverse_steps, r.reverse_steps);
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r));
  EXPECT_EQ(r.counters.revolutions_flagged, 2u);  // 7 (into the fault) and 8 (the fault and its aftermath)
  EXPECT_EQ(r.counters.missing_or_extra, 0u);
  EXPECT_EQ(r.counters.lost_index, 0u);
}

TEST(EdgeStreamFaults, LongCountingDownFlipsTheCountParityAndThePhaseIsDecidedAgain) {
  // 2500 edges counted down inside revolution 8: the unwrapped count ends up 5000 counts behind, so at the next
  // recognised index it snaps a whole revolution off the crank's. Only a phase decided again (not kept from
  // before the fault) gives firing TDC at 0 degrees afterwards. The index of revolution 9 comes as a jump from
  // near 2^32 (not recognised), so the count is back in step at the index of revolution 10.
  constexpr std::int64_t kRev = 8;
  Faults f;
  f.reverse_from = kRev * kCpr + 500;
  f.reverse_to = kRev * kCpr + 3000;
  const Outcome r = simulate(f, kDuration);
  check(r, {{index_time(kRev), index_time(kRev + 2)}, {index_time(r.last_revolution), kInf}});
  const double resumed = time_at(edge_theta(f.reverse_to));
  EXPECT_LE((index_time(kRev + 2) - resumed) * kOmega, 2 * 720.0);
  EXPECT_EQ(r.counters.reverse_steps, 2500u);
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r, 1));
  EXPECT_EQ(r.counters.revolutions_flagged, 1u);
  EXPECT_EQ(r.counters.lost_index, 0u);
}

TEST(EdgeStreamFaults, AStandingCrankLeavesAGapNotAnInterpolation) {
  // The crank stops for 0.2 s (no edges) in the middle of revolution 8, then turns on at the same speed.
  Faults f;
  f.pause_after_s = index_time(8) + 0.02;
  f.pause_s = 0.2;
  const Outcome r = simulate(f, kDuration);
  std::size_t in_gap = 0, after = 0;
  double max_err = 0.0, max_p_err = 0.0;
  for (const auto& [k, v] : r.frames) {
    const double t = static_cast<double>(k) * kFrame;
    if (t > f.pause_after_s + 1e-3 && t < f.pause_after_s + f.pause_s) ++in_gap;
    if (t < f.pause_after_s + f.pause_s || std::isnan(v.crank)) continue;
    const double theta = theta_at(t - f.pause_s);
    max_err = std::max(max_err, std::abs(angle_error(v.crank, wrap720(theta))));
    max_p_err = std::max(max_p_err, std::abs(v.p - pressure_pa(theta)));
    ++after;
  }
  std::printf("%zu frames in the pause, %zu after it: max error %.2e deg, %.0f Pa\n", in_gap, after, max_err,
              max_p_err);
  EXPECT_EQ(in_gap, 0u);
  EXPECT_GT(after, 12000u);  // 0.33 s
  // The stream stops shortly before the pause (the resampler's look-ahead) and resumes shortly after it.
  const auto last_before = r.frames.lower_bound(std::llround((f.pause_after_s + 1e-3) / kFrame));
  ASSERT_NE(last_before, r.frames.begin());
  EXPECT_GT(static_cast<double>(std::prev(last_before)->first) * kFrame, f.pause_after_s - 2e-3);
  ASSERT_NE(last_before, r.frames.end());
  EXPECT_LT(static_cast<double>(last_before->first) * kFrame, f.pause_after_s + f.pause_s + 2e-3);
  EXPECT_LT(max_err, 1e-3);
  EXPECT_LT(max_p_err, 2000.0);
  // The count is intact: the revolution with the pause is confirmed like any other.
  EXPECT_EQ(r.counters.revolutions_flagged, 0u);
}

TEST(EdgeStreamFaults, FourCountsPerEdge) {
  // x4 decoding with the scans clocked by one of the four edges: 14400 counts a revolution, 4 per scan.
  const Outcome clean = simulate(Faults{}, kDuration, true, 4);
  check(clean, {{index_time(clean.last_revolution), kInf}});
  EXPECT_EQ(clean.counters.revolutions_flagged, 0u);
  Faults f;
  f.missing = {8 * kCpr + 1234};
  f.extra = {12 * kCpr + 2345};
  const Outcome r = simulate(f, kDuration, true, 4);
  check(r, {{index_time(8), index_time(9)}, {index_time(12), index_time(13)}, {index_time(r.last_revolution), kInf}});
  EXPECT_EQ(r.counters.revolutions_checked, closed_revolutions(r));
  EXPECT_EQ(r.counters.revolutions_flagged, 2u);
  EXPECT_EQ(r.counters.missing_or_extra, 2u);
}
