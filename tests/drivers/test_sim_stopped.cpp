// The virtual engine at rest: the pressure sampled on the card's timer at the static pressure, through the chain's
// gain error, offset and floor, the crank angle unknown; the frames contiguous on the 40 kHz grid.
#include "drivers/sim/sim_stopped.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "drivers/sim/sim_generators.hpp"

namespace nd = noisemon::drivers;

TEST(SimStopped, PressureIsTheStaticPressureThroughTheChainOnTheTimer) {
  nd::sim::SimConfig config;
  config.stopped = true;
  config.static_pressure_bar = 20.0;  // a dead-weight tester on the transducer
  config.pressure_chain.offset_bar = 0.37;
  config.pressure_chain.gain_error = 0.04;
  const double t_first = 0.25;
  nd::sim::StoppedPressureGenerator gen(config, t_first);
  auto ring = std::make_unique<nd::BlockRing>(512);
  gen.advance(t_first + 1.0, *ring);
  auto block = std::make_unique<nd::SampleBlock>();
  std::int64_t next = 10000;  // 0.25 s at 40 kHz
  double sum = 0.0, sum2 = 0.0;
  std::size_t n = 0;
  while (ring->read(block.get(), 1) == 1) {
    ASSERT_EQ(block->first_index, next);
    ASSERT_EQ(block->channels, nd::kPressureStreamChannels);
    for (std::uint32_t f = 0; f < block->frames; ++f, ++n) {
      const double bar = 1e-5 * block->data[f * block->channels + nd::kPressureChannel];
      sum += bar, sum2 += bar * bar;
      EXPECT_TRUE(std::isnan(block->data[f * block->channels + nd::kCrankChannel]));
    }
    next += block->frames;
  }
  ASSERT_EQ(n, 40000u);
  const double mean = sum / static_cast<double>(n);
  const double sd = std::sqrt(sum2 / static_cast<double>(n) - mean * mean);
  const double floor = config.pressure_chain.floor_bar();  // independent per sample on the timer
  EXPECT_NEAR(mean, 20.0 * 1.04 + 0.37, 5.0 * floor / std::sqrt(static_cast<double>(n)));
  EXPECT_NEAR(sd / floor, 1.0, 0.03);
  EXPECT_EQ(gen.clipped_samples(), 0u);
}

TEST(SimStopped, TheCardReadsTheChainThroughTheConfiguredConversion) {
  // A 10 mV/bar sheet, the transducer 4 % steep and 0.37 bar high: the card converting with 10.4 mV/bar less
  // 0.37 / 1.04 bar reads the true 20 bar where the transducer puts out 20 * 1.04 + 0.37 on the sheet's scale.
  std::vector<double> p{20e5, 20e5};
  nd::sim::read_out_pressure({.nominal_mv_per_bar = 10.0, .card_mv_per_bar = 10.4, .card_offset_bar = 0.37 / 1.04},
                             p.data(), 1);
  EXPECT_NEAR(p[0], (20.0 * 10.0 / 10.4 - 0.37 / 1.04) * 1e5, 1e-6);
  std::vector<double> q{(20.0 * 1.04 + 0.37) * 1e5};
  nd::sim::read_out_pressure({.nominal_mv_per_bar = 10.0, .card_mv_per_bar = 10.4, .card_offset_bar = 0.37 / 1.04},
                             q.data(), 1);
  EXPECT_NEAR(q[0], 20e5, 1e-6);
  nd::sim::read_out_pressure({}, p.data() + 1, 1);  // no sheet: the chain's output is the reading
  EXPECT_EQ(p[1], 20e5);
}
