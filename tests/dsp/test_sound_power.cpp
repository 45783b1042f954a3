// ISO 3744 sound power: each part against an independent reference (the standard's own figures, closed-form
// geometry, a second way to remove the background).
#include "dsp/sound_power.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

namespace {

using namespace noisemon::dsp;

double energy(double level_db) { return std::pow(10.0, level_db / 10.0); }

TEST(SoundPower, BackgroundCorrectionRemovesTheBackgroundEnergy) {
  // Second method: subtract the background's energy from the total's.
  for (double difference : {6.01, 8.0, 10.0, 15.0}) {
    const double total = 70.0, background = total - difference;
    const double source_alone = 10 * std::log10(energy(total) - energy(background));
    const BackgroundCorrection k1 = background_correction(total, background);
    EXPECT_EQ(k1.validity, BandValidity::kCorrected) << difference;
    EXPECT_NEAR(total - k1.k1_db, source_alone, 1e-9) << difference;
  }
  // ISO 3744's figures: about 1.3 dB at the 6 dB limit, 0.5 dB at 10 dB.
  EXPECT_NEAR(background_correction(76.01, 70.0).k1_db, 1.25, 0.005);
  EXPECT_NEAR(background_correction(80.0, 70.0).k1_db, 0.46, 0.005);
}

TEST(SoundPower, Iso3744Of2010BoundsTheBandsWithinSixDecibelsAndStopsCorrectingAboveFifteen) {
  // 6 dB or less: K1 = 1.3 dB and an upper bound (ISO 3744:2010 8.2.3), however close or far below.
  for (double level : {76.0, 75.9, 70.0, 60.0}) {
    EXPECT_EQ(background_correction(level, 70.0).validity, BandValidity::kUpperBound) << level;
    EXPECT_EQ(background_correction(level, 70.0).k1_db, 1.3) << level;
  }
  EXPECT_EQ(background_correction(80.1, 70.0).validity, BandValidity::kCorrected);  // the 1994 edition stopped at 10
  EXPECT_EQ(background_correction(85.1, 70.0).validity, BandValidity::kUncorrected);
  EXPECT_EQ(background_correction(85.1, 70.0).k1_db, 0.0);
  EXPECT_EQ(background_correction(80.1, 70.0, 10.0).validity, BandValidity::kUncorrected);  // 1994's, when asked
  EXPECT_TRUE(std::isnan(background_correction(NAN, 70.0).k1_db));  // no measurement is no correction
}

TEST(SoundPower, MeteorologicalCorrectionsFollowTheAirsImpedance) {
  // C1 refers the level to a characteristic impedance of 400 Pa s/m: 10 lg(400 / rho c) with rho c = p sqrt(gamma /
  // (R T)) of dry air (gamma 1.4, R 287.05 J/(kg K)), which is 400 at 314 K and 101.325 kPa; within 0.01 dB.
  for (const auto& [celsius, kpa] : {std::pair{23.0, 101.325}, {40.0, 95.0}, {5.0, 103.0}, {-10.0, 99.0}}) {
    const double rho_c = kpa * 1e3 * std::sqrt(1.4 / (287.05 * (273.15 + celsius)));
    EXPECT_NEAR(reference_quantity_correction_c1_db(celsius, kpa), 10 * std::log10(400.0 / rho_c), 0.01) << celsius;
  }
  // At the reference atmosphere (23.0 deg C, 101.325 kPa) C2 vanishes; by hand: 15 lg(296.15 / 296) = 0.0033 dB.
  EXPECT_NEAR(radiation_impedance_correction_c2_db(23.0, 101.325), 0.0033, 5e-5);
  EXPECT_NEAR(reference_quantity_correction_c1_db(23.0, 101.325), -0.127, 5e-4);  // 5 lg(296.15 / 314)
  // Lower pressure, the same temperature: both rise by 10 lg(p0 / p).
  EXPECT_NEAR(radiation_impedance_correction_c2_db(23.0, 90.0) - radiation_impedance_correction_c2_db(23.0, 101.325),
              10 * std::log10(101.325 / 90.0), 1e-12);
}

TEST(SoundPower, EnvironmentalCorrectionFollowsTheRoomsAbsorption) {
  const double s = hemisphere_area_m2(1.75);
  EXPECT_NEAR(s, 2 * std::numbers::pi * 1.75 * 1.75, 1e-12);
  EXPECT_EQ(environmental_correction_k2_db(s, INFINITY), 0.0);  // free field
  // A = 4 S doubles the energy: 3 dB; A = 4 S / 9 multiplies it by ten.
  EXPECT_NEAR(environmental_correction_k2_db(s, 4 * s), 10 * std::log10(2.0), 1e-12);
  EXPECT_NEAR(environmental_correction_k2_db(s, 4 * s / 9), 10.0, 1e-12);
}

TEST(SoundPower, KeyPositionsLieOnTheHemisphereAtEqualAreaHeights) {
  const std::vector<Position> p = iso3744_key_positions(1.75);
  ASSERT_EQ(p.size(), 10u);
  for (const Position& q : p) EXPECT_NEAR(std::hypot(q[0], q[1], q[2]), 1.75, 0.01 * 1.75);  // table: 2 decimals
  // Archimedes: a zone's area is 2 pi r h, so three positions at each of z/r = 0.15, 0.45, 0.75 (zones 0.3 high)
  // and one at the top (a cap 0.1 high) each stand for a tenth of the hemisphere.
  std::vector<double> heights;
  for (const Position& q : p) heights.push_back(q[2] / 1.75);
  std::sort(heights.begin(), heights.end());
  const std::vector<double> expected = {0.15, 0.15, 0.15, 0.45, 0.45, 0.45, 0.75, 0.75, 0.75, 1.0};
  for (std::size_t i = 0; i < heights.size(); ++i) EXPECT_NEAR(heights[i], expected[i], 1e-12);
  EXPECT_TRUE(check_hemisphere(p, 1.75).ok());
}

TEST(SoundPower, AreaWeightsOfACubeFaceAndItsNeighbours) {
  // A position at the top and four on the rim, 90 degrees apart: the top one's cell is the directions whose largest
  // coordinate is z, a face of the cube seen from its centre: 4 pi / 6 of the sphere, a third of the hemisphere.
  const std::vector<Position> p = {{0, 0, 2}, {2, 0, 0}, {0, 2, 0}, {-2, 0, 0}, {0, -2, 0}};
  const std::vector<double> w = hemisphere_area_weights(p);
  ASSERT_EQ(w.size(), 5u);
  EXPECT_NEAR(w[0], 1.0 / 3.0, 2e-3);
  for (int i = 1; i < 5; ++i) EXPECT_NEAR(w[i], 1.0 / 6.0, 2e-3) << i;
  EXPECT_NEAR(std::accumulate(w.begin(), w.end(), 0.0), 1.0, 1e-9);
}

TEST(SoundPower, WeightedAverageOfEqualWeightsIsTheEnergyMean) {
  const std::vector<double> levels = {80, 83, 86, 79};
  const std::vector<double> equal(4, 0.25);
  EXPECT_NEAR(weighted_energy_average_db(levels, equal),
              10 * std::log10((energy(80) + energy(83) + energy(86) + energy(79)) / 4), 1e-12);
  // All the weight on one position: its level.
  EXPECT_NEAR(weighted_energy_average_db(levels, std::vector<double>{0, 0, 1, 0}), 86.0, 1e-12);
  EXPECT_TRUE(std::isnan(weighted_energy_average_db(levels, std::span<const double>(equal).subspan(0, 3))));
}

TEST(SoundPower, ChecksNameWhatIsWrongWithTheSurface) {
  std::vector<Position> p = iso3744_key_positions(1.75);
  p[3][2] = -0.1;                                        // below the floor
  p[6] = {p[6][0] * 1.2, p[6][1] * 1.2, p[6][2] * 1.2};  // 20 % outside the surface
  SurfaceCheck check = check_hemisphere(p, 1.75, 1.0);
  EXPECT_FALSE(check.ok());
  ASSERT_EQ(check.positions.size(), 10u);
  EXPECT_NE(check.positions[3].find("below the reflecting plane"), std::string::npos);
  EXPECT_NE(check.positions[6].find("not on the 1.75 m hemisphere"), std::string::npos);
  EXPECT_TRUE(check.positions[0].empty());
  ASSERT_EQ(check.surface.size(), 1u);  // 1.75 m < 2 x 1.0 m source
  EXPECT_NE(check.surface[0].find("twice the source"), std::string::npos);
  check = check_hemisphere(std::vector<Position>(p.begin(), p.begin() + 5), 0.8);
  EXPECT_EQ(check.surface.size(), 2u);  // under 1 m, fewer than ten
}

TEST(SoundPower, BandPowerAddsTheSurfaceTermAndRemovesTheCorrections) {
  // LW of a 1 m^2 surface is Lp; each doubling of the area adds 3 dB.
  EXPECT_NEAR(band_sound_power_db(80.0, 0.0, 0.0, 1.0), 80.0, 1e-12);
  EXPECT_NEAR(band_sound_power_db(80.0, 1.0, 0.5, 2.0), 78.5 + 10 * std::log10(2.0), 1e-12);
}

}  // namespace
