// The combustion figures from the crank-angle stream (one sample per encoder edge) rather than from the 40 kHz
// pressure: against closed forms written out here (a polytropic motored cycle on the slider-crank volume of Heywood
// eq. 2.5: IMEP 0, its exponent), the maximum of the edge samples themselves, and the same edges delivered in another
// order.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>
#include <vector>

#include "daemon/cycle_processor.hpp"
#include "dsp/math_constants.hpp"

using namespace noisemon;

namespace {

using noisemon::kPi;
constexpr int kAngleCycleFrames = 1600;  // 3000 rpm at 40 kHz
constexpr double kStepDeg = 0.1;         // the encoder: 183 kHz of edges, 4.5 a frame
constexpr double kPhaseDeg = 0.037;      // the encoder's edges lie this far after each multiple of the step
constexpr double kN = 1.32;              // the motored cycle's polytropic exponent
constexpr double kRippleHz = 30e3, kRipplePa = 0.2e5;  // above the 40 kHz stream's Nyquist: only the edges carry it
constexpr std::int64_t kFrames = 160 * 256;            // a second and a bit: 25 whole cycles

// The slider-crank volume (Heywood eq. 2.5) of the default engine, written out here.
double volume(double theta_deg) {
  const double bore = 0.086, stroke = 0.075, rod = 0.118, cr = 21.2, a = stroke / 2;
  const double vd = kPi / 4 * bore * bore * stroke, vc = vd / (cr - 1);
  const double th = theta_deg * kPi / 180;
  const double s = a * std::cos(th) + std::sqrt(rod * rod - a * a * std::sin(th) * std::sin(th));
  return vc + kPi / 4 * bore * bore * (rod + a - s);
}

// Compression and expansion polytropic from and to 1 bar at BDC; the gas exchange at 1 bar.
double motored(double theta_deg) {
  return std::abs(theta_deg) >= 180.0 ? 1.0e5 : 1.0e5 * std::pow(volume(180.0) / volume(theta_deg), kN);
}
double crank_of_instant(double frames) {
  return -360.0 + 720.0 * std::fmod(frames, kAngleCycleFrames) / kAngleCycleFrames;
}
double instant_of_edge(std::int64_t e) {
  return (kPhaseDeg + kStepDeg * static_cast<double>(e)) / 720.0 * kAngleCycleFrames;
}
double with_ripple(double theta_deg, double frames) {
  return motored(theta_deg) + kRipplePa * std::sin(2 * kPi * kRippleHz * frames / 40000.0);
}

struct Feed {
  bool angle_stream = true;            // the stream's info says it may come
  bool edges_sent = true;              // and it does
  bool angle_first = true;             // each second's edge blocks before (true) or after its 40 kHz blocks
  std::int64_t edges_lead_frames = 0;  // and this far ahead of them (a processing thread behind its drivers)
  std::function<bool(std::int64_t)> dropped = nullptr;  // edges the encoder missed
};

std::vector<daemon::CycleReport> run(const Feed& feed) {
  drivers::StreamInfo info;
  info.epoch_utime = 1'000'000;
  info.mic_count = 0;
  info.pressure_angle_step_deg = feed.angle_stream ? kStepDeg : 0.0;
  daemon::ProcessorConfig pc;
  pc.model = model::preset("linear");
  std::vector<daemon::CycleReport> reports;
  daemon::CycleProcessor p(pc, info, [&](const daemon::CycleReport& r) { reports.push_back(r); });
  std::vector<drivers::SampleBlock> edges, frames;
  drivers::SampleBlock b{};
  b.channels = drivers::kAngleStreamChannels;
  for (std::int64_t e = 0; instant_of_edge(e) < kFrames; ++e) {
    if (feed.dropped && feed.dropped(e)) continue;
    const double t = instant_of_edge(e), theta = crank_of_instant(t);
    if (b.frames == drivers::max_edges_per_angle_block(kStepDeg)) edges.push_back(b), b.frames = 0;
    if (b.frames == 0) b.first_index = static_cast<std::int64_t>(std::floor(t));
    b.data[b.frames * 2 + drivers::kAngleCrankChannel] = theta;
    b.data[b.frames * 2 + drivers::kAnglePressureChannel] = with_ripple(theta, t);
    ++b.frames;
  }
  edges.push_back(b);
  for (std::int64_t k = 0; k < kFrames; k += 256) {
    drivers::SampleBlock f{};
    f.first_index = k;
    f.frames = 256;
    f.channels = drivers::kPressureStreamChannels;
    for (std::uint32_t i = 0; i < 256; ++i) {
      const double theta = crank_of_instant(static_cast<double>(k + i));
      f.data[i * 2 + drivers::kPressureChannel] = motored(theta);  // what a resampler leaves of it: no ripple
      f.data[i * 2 + drivers::kCrankChannel] = theta;
    }
    frames.push_back(f);
  }
  // In chunks of a tenth of a second, the edges before or after the frames of the same stretch.
  std::size_t next_edge = 0;
  for (std::size_t c = 0; c < frames.size(); c += 16) {
    const std::int64_t until = c + 16 < frames.size() ? frames[c + 16].first_index : kFrames;
    const auto feed_edges = [&] {
      for (; next_edge < edges.size() && edges[next_edge].first_index < until + feed.edges_lead_frames; ++next_edge)
        if (feed.angle_stream && feed.edges_sent) p.add_pressure_angle(edges[next_edge]);
    };
    if (feed.angle_first) feed_edges();
    for (std::size_t i = c; i < std::min(c + 16, frames.size()); ++i) {
      p.add_pressure(frames[i]);
      p.process();
    }
    if (!feed.angle_first) feed_edges();
    p.process();
  }
  p.end_of_streams();
  p.process();
  return reports;
}

// The largest edge sample of cycle c (from -360 to +360 deg) and its angle, from the closed form.
std::pair<double, double> edge_peak(std::int64_t c) {
  double best = -1e300, at = 0;
  for (std::int64_t e = 0; e < static_cast<std::int64_t>(720.0 / kStepDeg); ++e) {
    const std::int64_t edge = c * static_cast<std::int64_t>(720.0 / kStepDeg) + e;
    const double t = instant_of_edge(edge), theta = crank_of_instant(t);
    if (const double v = with_ripple(theta, t); v > best) best = v, at = theta;
  }
  return {best, at};
}

}  // namespace

// A motored polytropic cycle with a 30 kHz ripple that only the 0.1 deg edges carry: the peak is the largest edge
// sample's (the metrics place it between the samples by a parabola: within a step of it, a little above it), the
// 40 kHz pressure's would miss the ripple; IMEP is the cycle's zero and the compression's exponent the cycle's own.
TEST(AngleStream, FiguresComeFromTheEncodersOwnSamples) {
  const std::vector<daemon::CycleReport> reports = run({});
  ASSERT_GE(reports.size(), 22u);
  for (const daemon::CycleReport& r : reports) {
    // Report k covers the cycle that begins at the (k + 1)-th boundary: engine cycle k + 1 from frame 0.
    const auto [peak, at] = edge_peak(r.cycle + 1);
    EXPECT_EQ(r.flags & daemon::kCycleAngleGap, 0) << r.cycle;
    EXPECT_GE(r.combustion.peak_pressure_pa, peak - 1.0) << r.cycle;
    EXPECT_LE(r.combustion.peak_pressure_pa, peak + 0.01e5) << r.cycle;
    EXPECT_NEAR(r.combustion.peak_angle_deg, at, kStepDeg) << r.cycle;
    EXPECT_NEAR(r.combustion.imep_gross_pa, 0.0, 0.005e5) << r.cycle;
    EXPECT_NEAR(r.combustion.imep_net_pa, 0.0, 0.005e5) << r.cycle;
    EXPECT_NEAR(r.combustion.n_compression, kN, 0.005) << r.cycle;
  }
  // Without the crank-angle stream the figures come from the 40 kHz pressure, which has no ripple.
  const std::vector<daemon::CycleReport> frames_only = run({.angle_stream = false});
  ASSERT_EQ(frames_only.size(), reports.size());
  EXPECT_LT(frames_only.back().combustion.peak_pressure_pa,
            edge_peak(frames_only.back().cycle + 1).first - 0.5 * kRipplePa);
}

// Edges the encoder missed: one is bridged (linear between its neighbours), five in a row are a gap that voids that
// cycle's figures, flagged; its neighbours keep theirs.
TEST(AngleStream, MissingEdgesVoidOnlyTheirCycleAndAreFlagged) {
  const std::int64_t per_cycle = static_cast<std::int64_t>(720.0 / kStepDeg);
  const std::int64_t gap_cycle = 10, single_cycle = 14;
  const std::vector<daemon::CycleReport> reports = run({.dropped = [&](std::int64_t e) {
    return (e >= gap_cycle * per_cycle + 3000 && e < gap_cycle * per_cycle + 3005) ||
           e == single_cycle * per_cycle + 3600;
  }});
  ASSERT_GE(reports.size(), 22u);
  for (const daemon::CycleReport& r : reports) {
    const bool gap = r.cycle + 1 == gap_cycle;
    EXPECT_EQ((r.flags & daemon::kCycleAngleGap) != 0, gap) << r.cycle;
    EXPECT_EQ(std::isnan(r.combustion.imep_net_pa), gap) << r.cycle;
    if (!gap) {
      EXPECT_NEAR(r.combustion.imep_gross_pa, 0.0, 0.005e5) << r.cycle;
    }
  }
}

// What is computed depends on the samples, not on when they came: edges a tenth of a second early or late (the first
// ones too: the processing waits for the stream's first block) give the same reports, number for number (a live run
// and its replay deliver the streams in different rhythms); so do edges 0.9 s ahead, 22 cycles (a processing thread
// that fell behind its drivers by a ring's span finds the edge ring drained far ahead of the frames).
TEST(AngleStream, TheOrderOfArrivalChangesNothing) {
  const std::vector<daemon::CycleReport> early = run({.angle_first = true}), late = run({.angle_first = false});
  const std::vector<daemon::CycleReport> far_ahead = run({.edges_lead_frames = 36000});
  ASSERT_EQ(early.size(), late.size());
  ASSERT_EQ(early.size(), far_ahead.size());
  ASSERT_GE(early.size(), 22u);
  for (const std::vector<daemon::CycleReport>* other : {&late, &far_ahead}) {
    for (std::size_t i = 0; i < early.size(); ++i) {
      const daemon::CycleReport& r = (*other)[i];
      EXPECT_EQ(early[i].flags & daemon::kCycleAngleGap, 0) << i;
      EXPECT_EQ(early[i].combustion.peak_pressure_pa, r.combustion.peak_pressure_pa) << i;
      EXPECT_EQ(early[i].combustion.imep_net_pa, r.combustion.imep_net_pa) << i;
      EXPECT_EQ(early[i].combustion.n_compression, r.combustion.n_compression) << i;
      EXPECT_EQ(early[i].flags, r.flags) << i;
    }
  }
}

// A recording of a source that had the stream but did not record it (an older log): after half a second of pressure
// without an edge the processing goes on, the figures from the 40 kHz pressure, every cycle reported.
TEST(AngleStream, AStreamThatNeverComesIsNotWaitedForLong) {
  const std::vector<daemon::CycleReport> none = run({.edges_sent = false}), frames_only = run({.angle_stream = false});
  ASSERT_EQ(none.size(), frames_only.size());
  ASSERT_GE(none.size(), 22u);
  for (std::size_t i = 0; i < none.size(); ++i) {
    EXPECT_EQ(none[i].flags & daemon::kCycleAngleGap, 0) << i;
    EXPECT_EQ(none[i].combustion.peak_pressure_pa, frames_only[i].combustion.peak_pressure_pa) << i;
  }
}
