// Effects that switch on mid-run ([[sim.effects]] onset_s, ramp_s): the schedule's weights, and the generators'
// output against the clean engine's times the effect's analytic size.
#include "drivers/sim/sim_effect_schedule.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "drivers/sim/sim_generators.hpp"

namespace nd = noisemon::drivers;
namespace nm = noisemon::model;

namespace {

constexpr double kStart = 0.05;  // the generators' first frame, s on the source clock

// Channel 0 of every 40 kHz frame a generator writes up to t_end (all channels: every_channel), advanced in 10 ms
// steps, from the source's first frame (a stretch before the first block stays NaN).
template <class Generator>
std::vector<double> generate(const nd::sim::SimConfig& cfg, double t_end, bool every_channel = false) {
  Generator g(cfg, kStart);
  nd::BlockRing ring(4096);
  std::vector<double> out;
  nd::SampleBlock b;
  for (double t = kStart + 0.01; t < t_end + 1e-12; t += 0.01) {
    g.advance(std::min(t, t_end), ring);
    while (ring.read(&b, 1)) {
      const std::size_t keep = every_channel ? b.channels : 1;
      const auto at = static_cast<std::size_t>(b.first_index - g.first_index()) * keep;
      if (out.size() < at) out.resize(at, std::numeric_limits<double>::quiet_NaN());
      for (std::size_t f = 0; f < static_cast<std::size_t>(b.frames); ++f)
        out.insert(out.end(), b.data + f * b.channels, b.data + f * b.channels + keep);
    }
  }
  return out;
}

nd::sim::SimConfig scheduled(const char* effect, double onset_s, double ramp_s) {
  nd::sim::SimConfig c;
  c.seed = 5;
  c.scheduled_effects.push_back({nm::engine::parse_effect(effect), onset_s, ramp_s});
  return c;
}

}  // namespace

TEST(SimEffectSchedule, WeightIsZeroBeforeOnsetLinearOverTheRampAndOneAfter) {
  const nd::sim::ScheduledEffect step{nm::engine::parse_effect("mic_gain=3"), 90.0, 0.0};
  EXPECT_EQ(nd::sim::effect_weight(step, 89.999), 0.0);
  EXPECT_EQ(nd::sim::effect_weight(step, 90.0), 1.0);
  const nd::sim::ScheduledEffect ramp{nm::engine::parse_effect("mic_gain=1"), 10.0, 600.0};
  EXPECT_EQ(nd::sim::effect_weight(ramp, 5.0), 0.0);
  EXPECT_DOUBLE_EQ(nd::sim::effect_weight(ramp, 310.0), 0.5);
  EXPECT_EQ(nd::sim::effect_weight(ramp, 700.0), 1.0);
  EXPECT_THROW((void)nd::sim::cumulative_effects(nm::engine::parse_effects({"mic_gain=2"}), {step}, 1),
               std::invalid_argument);
}

// A step of mic_gain on microphone 4: every other microphone bit-identical to the clean engine throughout,
// microphone 4 bit-identical before the onset and exactly 10^(6/20) times the clean signal once the resampler has
// passed the step (its kernel spans under 2 ms).
TEST(SimEffectSchedule, MicGainStepScalesOneMicrophoneFromItsOnsetOnly) {
  const double onset = 0.1;  // s after the first frame
  const auto clean = generate<nd::sim::MicGenerator>(nd::sim::SimConfig{.seed = 5}, 0.25, true);
  const auto stepped = generate<nd::sim::MicGenerator>(scheduled("mic_gain=6,mic=4", onset, 0.0), 0.25, true);
  ASSERT_EQ(clean.size(), stepped.size());
  const std::size_t mics = 10, frames = clean.size() / mics;
  const double g = std::pow(10.0, 6.0 / 20.0);
  const auto onset_frame = static_cast<std::size_t>(onset * 40000.0);
  std::size_t checked_after = 0;
  for (std::size_t f = 0; f < frames; ++f)
    for (std::size_t m = 0; m < mics; ++m) {
      const double a = clean[f * mics + m], b = stepped[f * mics + m];
      if (m != 3 || f + 80 < onset_frame) {
        ASSERT_EQ(a, b) << "frame " << f << " mic " << m + 1;
      } else if (f > onset_frame + 80) {
        ASSERT_NEAR(b, g * a, 1e-6 + 1e-9 * std::abs(a)) << "frame " << f;
        ++checked_after;
      }
    }
  EXPECT_GT(checked_after, 3500u);
}

// A ramp of 0.1 s from 0.05 s: half way through, the factor is 1 + (g - 1) / 2 (amplitude-linear growth).
TEST(SimEffectSchedule, MicGainRampGrowsLinearly) {
  const auto clean = generate<nd::sim::MicGenerator>(nd::sim::SimConfig{.seed = 5}, 0.25, true);
  const auto ramped = generate<nd::sim::MicGenerator>(scheduled("mic_gain=6,mic=2", 0.05, 0.1), 0.25, true);
  const std::size_t mics = 10;
  const double g = std::pow(10.0, 6.0 / 20.0);
  for (const double at : {0.075, 0.1, 0.125}) {
    // Energy ratio over 1 ms about `at`: the factor squared (the factor moves 0.5 % over the window).
    const auto centre = static_cast<std::size_t>(at * 40000.0);
    double e_clean = 0.0, e_ramp = 0.0;
    for (std::size_t f = centre - 20; f < centre + 20; ++f) {
      e_clean += clean[f * mics + 1] * clean[f * mics + 1];
      e_ramp += ramped[f * mics + 1] * ramped[f * mics + 1];
    }
    const double expected = 1.0 + (g - 1.0) * (at - 0.05) / 0.1;
    EXPECT_NEAR(std::sqrt(e_ramp / e_clean), expected, 0.01) << "at " << at << " s";
  }
}

// transducer_noise acts on the measured pressure alone: identical before its onset, then the clean pressure plus
// white noise as loud on the 40 kHz grid as the same rms configured as the pressure chain's own floor (a separate
// code path: PressureChain's counter-based floor) adds.
TEST(SimEffectSchedule, TransducerNoiseStepAddsWhatTheSameFloorAdds) {
  const double onset = 0.1;
  nd::sim::SimConfig quiet{.seed = 5};
  quiet.pressure_chain.noise_bar = 0.0;
  quiet.pressure_chain.adc_bits = 0;
  nd::sim::SimConfig floor = quiet;
  floor.pressure_chain.noise_bar = 0.5;
  nd::sim::SimConfig noisy = quiet;
  noisy.scheduled_effects.push_back({nm::engine::parse_effect("transducer_noise=0.5"), onset, 0.0});
  const auto clean = generate<nd::sim::PressureGenerator>(quiet, 0.3);
  const auto with_floor = generate<nd::sim::PressureGenerator>(floor, 0.3);
  const auto stepped = generate<nd::sim::PressureGenerator>(noisy, 0.3);
  const std::size_t n = std::min({clean.size(), with_floor.size(), stepped.size()});
  ASSERT_GT(n, 8000u);
  const auto onset_frame = static_cast<std::size_t>(onset * 40000.0);
  double ss_effect = 0.0, ss_floor = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (std::isnan(clean[i])) continue;  // before the decoder's first block
    if (i + 80 < onset_frame) ASSERT_EQ(clean[i], stepped[i]) << "frame " << i;
    if (i > onset_frame + 80) {
      ss_effect += (stepped[i] - clean[i]) * (stepped[i] - clean[i]);
      ss_floor += (with_floor[i] - clean[i]) * (with_floor[i] - clean[i]);
    }
  }
  ASSERT_GT(ss_floor, 0.0);
  EXPECT_GT(ss_effect, 0.0);
  EXPECT_NEAR(std::sqrt(ss_effect / ss_floor), 1.0, 0.05);
}
