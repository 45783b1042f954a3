// The virtual engine's operating-point schedule ([[sim.schedule]]): where a change lands (the first cycle boundary
// at or after its instant), a ramp cycle by cycle, the crank angle continuous through a change of speed, and the
// encoder-clocked pressure stream that the decoder makes of it: cycle boundaries 120 / n apart before and after.
#include "drivers/sim/sim_operating_schedule.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "drivers/sim/sim_generators.hpp"

namespace nd = noisemon::drivers;
namespace nm = noisemon::model;

namespace {

nm::engine::OperatingCondition at(double rpm, double load = 0.0, double soi = 18.0) {
  return {.speed_rpm = rpm, .load_nm = load, .soi_deg_btdc = soi, .motored = false};
}

}  // namespace

// 3000 rpm: a cycle every 40 ms, cycle k from 0.04 k s. A step asked for 0.2 s after a first frame at 0.05 s
// (0.25 s) lands on the boundary at 0.28 s, cycle 7; at 6000 rpm the next boundary is 20 ms later.
TEST(OperatingProfile, AStepLandsOnTheFirstCycleBoundaryAfterItsInstant) {
  const nd::sim::OperatingProfile p(at(3000.0), {{.at_s = 0.2, .ramp_s = 0.0, .condition = at(6000.0, 10.0, 12.0)}},
                                    0.01, 0.05);
  EXPECT_EQ(p.condition(6).speed_rpm, 3000.0);
  EXPECT_EQ(p.condition(-3).speed_rpm, 3000.0);  // the pre-roll's cycles: the first operating point
  EXPECT_EQ(p.condition(7).speed_rpm, 6000.0);
  EXPECT_EQ(p.condition(7).load_nm, 10.0);
  EXPECT_EQ(p.condition(7).soi_deg_btdc, 12.0);
  EXPECT_EQ(p.condition(1000).speed_rpm, 6000.0);
  const nm::CrankKinematics& k = p.kinematics();
  EXPECT_NEAR(k.theta_deg(0.28), 720.0 * 7 - 360.0, 1e-9);
  EXPECT_NEAR(k.theta_deg(0.30), 720.0 * 8 - 360.0, 1e-9);
  EXPECT_NEAR(k.theta_deg(0.24), 720.0 * 6 - 360.0, 1e-9);
  EXPECT_NEAR(k.time_s(720.0 * 9 - 360.0), 0.32, 1e-12);
  // Continuous through the step; the mean speed changes there.
  EXPECT_NEAR(k.theta_deg(0.28 - 1e-9), k.theta_deg(0.28 + 1e-9), 1e-4);
  EXPECT_NEAR(k.speed_rpm(0.28 - 1e-6), 3000.0 * (1.0 - 0.01 * std::cos(M_PI * 13.0)), 0.1);
  EXPECT_NEAR(k.speed_rpm(0.28 + 1e-6), 6000.0 * 1.01, 0.1);
  for (double t = 0.0; t < 0.5; t += 0.0037) ASSERT_NEAR(k.time_s(k.theta_deg(t)), t, 1e-12) << t;
  EXPECT_EQ(p.min_speed_rpm(), 3000.0);
  EXPECT_EQ(p.max_speed_rpm(), 6000.0);
}

// 1000 -> 2000 rpm over 0.32 s (a mean cycle of 80 ms: 4 cycles): 1250, 1500, 1750, 2000 rpm; the cycles' lengths
// follow (96, 80, 68.57 ms), load and SOI ramp with the speed.
TEST(OperatingProfile, ARampChangesCycleByCycle) {
  const nd::sim::OperatingProfile p(at(1000.0, 0.0, 20.0),
                                    {{.at_s = 0.1, .ramp_s = 0.32, .condition = at(2000.0, 20.0, 12.0)}}, 0.0, 0.0);
  // 1000 rpm: 120 ms cycles, the step's first boundary is 0.12 s (cycle 1).
  const double expected[] = {1000.0, 1250.0, 1500.0, 1750.0, 2000.0, 2000.0};
  for (int c = 0; c < 6; ++c) EXPECT_NEAR(p.condition(c).speed_rpm, expected[c], 1e-9) << c;
  EXPECT_NEAR(p.condition(2).load_nm, 10.0, 1e-9);
  EXPECT_NEAR(p.condition(2).soi_deg_btdc, 16.0, 1e-9);
  const nm::CrankKinematics& k = p.kinematics();
  double boundary = 0.12;
  for (int c = 1; c < 6; ++c) {
    EXPECT_NEAR(k.time_s(720.0 * c - 360.0), boundary, 1e-12) << c;
    boundary += 120.0 / expected[c];
  }
}

TEST(OperatingProfile, ValidationNamesTheStepAndField) {
  const auto message = [](const std::vector<nd::sim::OperatingStep>& s) {
    try {
      nd::sim::validate_operating_schedule(s);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(message({{.at_s = 10.0, .condition = at(2000.0)}, {.at_s = 20.0, .condition = at(1500.0)}}), "");
  EXPECT_NE(message({{.at_s = 10.0, .ramp_s = 15.0, .condition = at(2000.0)}, {.at_s = 20.0, .condition = at(1500.0)}})
                .find("sim.schedule[1]: at_s"),
            std::string::npos);
  EXPECT_NE(message({{.at_s = 10.0, .condition = at(0.0)}}).find("sim.schedule[0]: speed_rpm"), std::string::npos);
  EXPECT_NE(message({{.at_s = 10.0, .condition = at(2000.0, -1.0)}}).find("load_nm"), std::string::npos);
  EXPECT_NE(message({{.at_s = 10.0, .condition = at(2000.0, 0.0, 70.0)}}).find("soi_deg_btdc"), std::string::npos);
}

// The encoder-clocked pressure stream through the card's decoder: a step from 2000 to 3450 rpm gives crank-angle
// wraps 60 ms apart before and 34.8 ms after, a trusted angle throughout (the decoder checks every revolution's
// count and the phase), and a higher peak pressure at full load.
TEST(OperatingProfile, TheDecodedStreamFollowsAStepOfSpeedAndLoad) {
  nd::sim::SimConfig cfg;
  cfg.speed_rpm = 2000.0;
  cfg.seed = 3;
  cfg.operating_schedule.push_back({.at_s = 0.3, .ramp_s = 0.0, .condition = at(3450.0, 20.0, 18.0)});
  const double start = 0.05;
  nd::sim::PressureGenerator g(cfg, start);
  nd::BlockRing ring(8192);
  for (double t = start + 0.01; t < start + 0.8; t += 0.01) g.advance(t, ring);
  std::vector<double> crank, pressure;
  nd::SampleBlock b;
  while (ring.read(&b, 1))
    for (std::uint32_t f = 0; f < b.frames; ++f) {
      pressure.push_back(b.data[f * b.channels + nd::kPressureChannel]);
      crank.push_back(b.data[f * b.channels + nd::kCrankChannel]);
    }
  ASSERT_GT(crank.size(), 25000u);
  std::vector<double> wraps_s;  // where the angle wraps from 360 to -360 (interpolated)
  std::size_t nan_after_lock = 0;
  for (std::size_t i = 1; i < crank.size(); ++i) {
    if (std::isnan(crank[i])) {
      nan_after_lock += wraps_s.empty() ? 0 : 1;
      continue;
    }
    if (crank[i] < crank[i - 1] - 360.0) {
      const double over = (crank[i] + 720.0 - crank[i - 1]);
      wraps_s.push_back((static_cast<double>(i - 1) + (360.0 - crank[i - 1]) / over) / 40000.0 + start);
    }
  }
  EXPECT_EQ(nan_after_lock, 0u);
  ASSERT_GE(wraps_s.size(), 10u);
  std::size_t before = 0, after = 0;
  for (std::size_t i = 1; i < wraps_s.size(); ++i) {
    const double gap = wraps_s[i] - wraps_s[i - 1];
    if (wraps_s[i] < start + 0.3) {
      EXPECT_NEAR(gap, 0.060, 5e-5) << wraps_s[i];
      ++before;
    } else if (wraps_s[i - 1] > start + 0.3 + 0.06) {
      EXPECT_NEAR(gap, 120.0 / 3450.0, 5e-5) << wraps_s[i];
      ++after;
    }
  }
  EXPECT_GE(before, 3u);
  EXPECT_GE(after, 8u);
  // Peak pressure of the first and the last full cycle: the full-load cycle fires harder.
  const auto peak = [&](double from_s, double to_s) {
    double m = 0.0;
    for (std::size_t i = static_cast<std::size_t>((from_s - start) * 40000.0);
         i < static_cast<std::size_t>((to_s - start) * 40000.0); ++i)
      if (!std::isnan(pressure[i])) m = std::max(m, pressure[i]);
    return m;
  };
  EXPECT_GT(peak(wraps_s.back() - 0.0348, wraps_s.back()), 1.1 * peak(wraps_s[0], wraps_s[1]));
}
