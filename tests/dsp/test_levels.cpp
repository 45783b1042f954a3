// Levels re 20 uPa, energy sums and averages, ISO 3744 area term and background correction: analytic
// values and second methods written independently here.
#include "dsp/levels.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

using namespace noisemon::dsp;

TEST(Levels, LevelOfReferenceAndOfOnePascal) {
  EXPECT_NEAR(level_db(20e-6 * 20e-6), 0.0, 1e-12);
  EXPECT_NEAR(level_db(1.0), 93.9794, 1e-4);  // 1 Pa rms
  EXPECT_EQ(level_db(0.0), -INFINITY);
  for (double l : {-20.0, 0.0, 94.0, 180.0}) EXPECT_NEAR(level_db(mean_square_from_level(l)), l, 1e-12);
}

TEST(Levels, SineLevelFromSampledMeanSquare) {
  // A sine of amplitude A has rms A / sqrt(2): L = 20 log10(A / sqrt2 / 20 uPa). Mean square from samples
  // over a whole number of periods.
  const double amp = 3.0, fs = 40000, f = 1000;
  const int n = 4000;  // 100 periods
  double ms = 0;
  for (int i = 0; i < n; ++i) {
    const double x = amp * std::sin(2 * std::numbers::pi * f * i / fs + 0.3);
    ms += x * x;
  }
  ms /= n;
  EXPECT_NEAR(level_db(ms), 20 * std::log10(amp / std::sqrt(2.0) / 20e-6), 1e-9);
}

TEST(Levels, EnergySumAndAverage) {
  const std::vector<double> two = {80.0, 80.0};
  EXPECT_NEAR(energy_sum_db(two), 83.0103, 1e-4);  // +10 log10(2)
  EXPECT_NEAR(energy_average_db(two), 80.0, 1e-12);
  const std::vector<double> mixed = {60.0, 70.0};
  EXPECT_NEAR(energy_sum_db(mixed), 70.4139, 1e-4);      // 10 log10(1e6 + 1e7)
  EXPECT_NEAR(energy_average_db(mixed), 67.4036, 1e-4);  // 10 log10(5.5e6)
  const std::vector<double> ten(10, 50.0);
  EXPECT_NEAR(energy_sum_db(ten), 60.0, 1e-12);
  EXPECT_NEAR(energy_average_db(ten), 50.0, 1e-12);
  const std::vector<double> with_silence = {-INFINITY, 50.0};
  EXPECT_NEAR(energy_sum_db(with_silence), 50.0, 1e-12);
  EXPECT_EQ(energy_sum_db({}), -INFINITY);
  EXPECT_TRUE(std::isnan(energy_average_db({})));
}

TEST(Levels, HemisphereAreaTermAndSoundPower) {
  EXPECT_NEAR(hemisphere_area_term_db(1.75), 12.84, 0.005);  // 10 log10(2 pi 1.75^2)
  EXPECT_NEAR(hemisphere_area_term_db(1.0), 10 * std::log10(2 * std::numbers::pi), 1e-12);
  // Doubling the radius quadruples the area: +6.02 dB.
  EXPECT_NEAR(hemisphere_area_term_db(3.5) - hemisphere_area_term_db(1.75), 20 * std::log10(2.0), 1e-12);
  EXPECT_NEAR(sound_power_level_db(80.0, 1.75), 92.84, 0.005);
}

TEST(Levels, AttenuationIsCplMinusSplA) { EXPECT_DOUBLE_EQ(attenuation_db(190.0, 85.5), 104.5); }
