// The calibrator's tone measured as `noisemon calibrate` measures it, on tones written here from their definition:
// the frequency, the rms (a sine of amplitude A has rms A / sqrt 2), a level step inside the measurement, and a tone
// looked for where it is not.
#include "dsp/calibrator_tone.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

namespace {

std::vector<double> tone(double f_hz, double amplitude, double seconds, double noise_rms, double step_db = 0.0) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, noise_rms);
  std::vector<double> x(static_cast<std::size_t>(seconds * 40000.0));
  for (std::size_t k = 0; k < x.size(); ++k) {
    const double gain = k >= x.size() / 2 ? std::pow(10.0, step_db / 20.0) : 1.0;
    x[k] = gain * amplitude * std::sin(2.0 * std::numbers::pi * f_hz * static_cast<double>(k) / 40000.0 + 0.3) +
           noise(rng);
  }
  return x;
}

}  // namespace

TEST(CalibratorTone, FrequencyAndRmsOfAToneOffItsNominalFrequencyInNoise) {
  // A 94 dB calibrator (1.0024 Pa rms) 3.7 Hz off its 1 kHz, beside 60 dB of room noise (0.02 Pa rms).
  const double rms = 20e-6 * std::pow(10.0, 94.0 / 20.0);
  const auto x = tone(1003.7, rms * std::sqrt(2.0), 3.0, 0.02);
  const auto m = noisemon::dsp::measure_tone(x, 40000.0, 1000.0);
  EXPECT_NEAR(m.frequency_hz, 1003.7, 0.05);
  EXPECT_NEAR(20.0 * std::log10(m.rms / rms), 0.0, 0.01);
  EXPECT_NEAR(m.total_rms, std::sqrt(rms * rms + 0.02 * 0.02), 0.002);
  EXPECT_LT(m.fluctuation_db, 0.02);
  EXPECT_EQ(m.half_seconds, 6u);
}

TEST(CalibratorTone, AStepInTheLevelIsTheFluctuation) {
  const auto m = noisemon::dsp::measure_tone(tone(250.0, 1.0, 4.0, 0.001, 0.3), 40000.0, 250.0);
  EXPECT_NEAR(m.fluctuation_db, 0.3, 0.02);
}

TEST(CalibratorTone, AToneLookedForWhereItIsNotIsNearlyNothingOfTheSignal) {
  const auto m = noisemon::dsp::measure_tone(tone(1000.0, 1.0, 2.0, 0.0), 40000.0, 250.0);
  EXPECT_LT(m.rms, 0.1 * m.total_rms);  // below -20 dB of it (what leaks into 10 ms blocks); the command wants -1 dB
  EXPECT_THROW(noisemon::dsp::measure_tone(tone(1000.0, 1.0, 0.5, 0.0), 40000.0, 1000.0), std::invalid_argument);
}
