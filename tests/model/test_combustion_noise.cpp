// Combustion-noise level through a structure-attenuation curve, against references outside the code under test:
// the thesis's eq. (4.1) recomputed here from its constants re-typed from the thesis (Cao 2015, sec. 4.3.1), band
// values of that curve computed independently (Python, same constants), the A-weighting of IEC 61672-1:2013
// Table 3 (values re-typed, rounded to 0.1 dB there), and energy sums done by hand.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "dsp/math_constants.hpp"
#include "model/combustion_noise.hpp"

namespace nm = noisemon::model;

namespace {

using noisemon::kNaN;

// IEC 61672-1:2013 Table 3, A-weighting at the nominal 1/3-octave frequencies 20 Hz ... 20 kHz, dB (0.1 dB steps).
constexpr std::array<double, nm::kSaBandCount> kIecA{
    -50.5, -44.7, -39.4, -34.6, -30.2, -26.2, -22.5, -19.1, -16.1, -13.4, -10.9, -8.6, -6.6, -4.8, -3.2, -1.9,
    -0.8,  0.0,   0.6,   1.0,   1.2,   1.3,   1.2,   1.0,   0.5,   -0.1,  -1.1,  -2.5, -4.3, -6.6, -9.3};

// Thesis eq. (4.1) with its constants, re-typed: ka = 11.885, break at 100 Hz, zeta = 0.35, resonance at 5 kHz.
double eq_4_1_attenuation_db(double f_hz) {
  const double two_pi = 2.0 * std::numbers::pi;
  const double ka = 11.885, wb = two_pi * 100.0, zeta = 0.35, wn = two_pi * 5000.0;
  const std::complex<double> s(0.0, two_pi * f_hz);
  return -20.0 * std::log10(std::abs(ka * (s + wb) / (s * s + 2.0 * zeta * wn * s + wn * wn)));
}

nm::StructureAttenuation flat_curve(double db) {
  nm::StructureAttenuation sa;
  sa.db.fill(db);
  sa.source = "test: flat";
  return sa;
}

// db[i] = i: the interpolated value is the position on the band axis itself.
nm::StructureAttenuation ramp_curve() {
  nm::StructureAttenuation sa;
  for (std::size_t i = 0; i < nm::kSaBandCount; ++i) sa.db[i] = static_cast<double>(i);
  sa.source = "test: ramp";
  return sa;
}

std::vector<double> nominal_bands() { return {nm::kSaNominalBandsHz.begin(), nm::kSaNominalBandsHz.end()}; }

double energy_sum(const std::vector<double>& levels) {
  double e = 0.0;
  for (double l : levels) e += std::pow(10.0, l / 10.0);
  return 10.0 * std::log10(e);
}

}  // namespace

TEST(CombustionNoise, BandFrequenciesAreTheIec61260Base10Mids) {
  EXPECT_NEAR(nm::sa_band_exact_mid_hz(0), 19.9526, 1e-4);
  EXPECT_DOUBLE_EQ(nm::sa_band_exact_mid_hz(17), 1000.0);
  EXPECT_NEAR(nm::sa_band_exact_mid_hz(24), 5011.87, 1e-2);
  EXPECT_NEAR(nm::sa_band_exact_mid_hz(30), 19952.6, 0.1);
  for (std::size_t i = 0; i < nm::kSaBandCount; ++i)  // nominal labels round the exact mids within 3 %
    EXPECT_NEAR(nm::kSaNominalBandsHz[i] / nm::sa_band_exact_mid_hz(i), 1.0, 0.03) << i;
}

TEST(CombustionNoise, Cao2015CurveIsEq41AtEveryBand) {
  const auto& sa = nm::cao2015_eq_4_1_attenuation();
  for (std::size_t i = 0; i < nm::kSaBandCount; ++i) {
    const double f = nm::sa_band_exact_mid_hz(i);
    EXPECT_NEAR(sa.db[i], eq_4_1_attenuation_db(f), 1e-9) << f;
    EXPECT_NEAR(nm::structure_attenuation_db(sa, f), eq_4_1_attenuation_db(f), 1e-9) << f;
  }
  EXPECT_NE(std::string(sa.source).find("eq. (4.1)"), std::string::npos);
}

TEST(CombustionNoise, Cao2015CurveMatchesValuesComputedIndependently) {
  // Python, from the thesis constants, at the exact mid-band frequencies.
  const auto& sa = nm::cao2015_eq_4_1_attenuation();
  EXPECT_NEAR(sa.db[0], 102.2528, 1e-3);  // 20 Hz
  EXPECT_NEAR(sa.db[7], 99.4095, 1e-3);   // 100 Hz
  EXPECT_NEAR(sa.db[17], 82.1160, 1e-3);  // 1 kHz
  EXPECT_NEAR(sa.db[24], 65.3434, 1e-3);  // 5 kHz
  EXPECT_NEAR(sa.db[30], 80.0497, 1e-3);  // 20 kHz
  // Below the 100 Hz break the curve flattens towards -20 lg(ka wb / wn^2) = 102.42 dB.
  EXPECT_NEAR(eq_4_1_attenuation_db(1.0), 102.4224, 1e-3);
  // Least attenuation in the 5 kHz band (thesis sec. 4.2: "least around 5,000 Hz").
  std::size_t least = 0;
  for (std::size_t i = 1; i < nm::kSaBandCount; ++i)
    if (sa.db[i] < sa.db[least]) least = i;
  EXPECT_EQ(nm::kSaNominalBandsHz[least], 5000.0);
}

TEST(CombustionNoise, InterpolatesLinearlyInLogFrequency) {
  const auto sa = ramp_curve();
  for (double f : {20.0, 22.4, 100.0, 141.0, 1000.0, 1122.0, 3000.0, 7000.0, 19000.0})
    EXPECT_NEAR(nm::structure_attenuation_db(sa, f), 10.0 * std::log10(f / 1000.0) + 17.0, 1e-9) << f;
  // Geometric mean of two neighbouring mids: half way.
  const double f = std::sqrt(nm::sa_band_exact_mid_hz(3) * nm::sa_band_exact_mid_hz(4));
  EXPECT_NEAR(nm::structure_attenuation_db(sa, f), 3.5, 1e-9);
}

TEST(CombustionNoise, EndBandsHoldToTheirOuterEdgesAndNoFurther) {
  const auto sa = ramp_curve();
  EXPECT_DOUBLE_EQ(nm::structure_attenuation_db(sa, 18.0), 0.0);      // inside the 20 Hz band (edge 17.8 Hz)
  EXPECT_DOUBLE_EQ(nm::structure_attenuation_db(sa, 20000.0), 30.0);  // nominal 20 kHz lies above its mid
  EXPECT_DOUBLE_EQ(nm::structure_attenuation_db(sa, 22000.0), 30.0);  // edge 22.4 kHz
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(sa, 17.0)));
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(sa, 23000.0)));
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(sa, 0.0)));
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(sa, -100.0)));
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(sa, kNaN)));
}

TEST(CombustionNoise, Cao2015InterpolationStaysWithinItsStatedErrorOfEq41) {
  const auto& sa = nm::cao2015_eq_4_1_attenuation();
  double worst = 0.0;
  for (double f = 20.0; f < 20000.0; f *= 1.01)
    worst = std::max(worst, std::abs(nm::structure_attenuation_db(sa, f) - eq_4_1_attenuation_db(f)));
  EXPECT_LT(worst, 0.36);  // the header states 0.35 dB
  EXPECT_GT(worst, 0.2);   // and it is the resonance, not zero: the check sees the interpolation
}

TEST(CombustionNoise, SingleBandToneIsCplMinusSaPlusA) {
  const auto sa = flat_curve(60.0);
  const std::vector<double> f{100.0};
  EXPECT_NEAR(nm::combustion_noise_level_db(std::vector<double>{150.0}, f, sa), 150.0 - 60.0 - 19.1, 0.06);
  EXPECT_NEAR(nm::combustion_noise_level_db(std::vector<double>{150.0}, std::vector<double>{1000.0}, sa), 90.0, 0.01);
  EXPECT_NEAR(nm::combustion_noise_level_db(std::vector<double>{150.0}, std::vector<double>{4000.0}, sa), 91.0, 0.06);
  // Through the thesis curve at the 5 kHz band: 150 - 65.3434 + 0.549 (A at 5011.87 Hz), by hand.
  const std::vector<double> f5{nm::sa_band_exact_mid_hz(24)};
  EXPECT_NEAR(nm::combustion_noise_level_db(std::vector<double>{150.0}, f5, nm::cao2015_eq_4_1_attenuation()), 85.2056,
              2e-3);
}

TEST(CombustionNoise, FlatSpectrumSumsByHand) {
  // 140 dB in every band, SA 60 dB: 80 + 10 lg sum 10^(A_b/10) over IEC Table 3 = 80 + 11.935 dB.
  std::vector<double> cpl(nm::kSaBandCount, 140.0);
  EXPECT_NEAR(nm::combustion_noise_level_db(cpl, nominal_bands(), flat_curve(60.0)), 91.935, 0.05);
  // Through the thesis curve at the exact mids (Python: 80.7782 dB).
  std::vector<double> mids;
  for (std::size_t i = 0; i < nm::kSaBandCount; ++i) mids.push_back(nm::sa_band_exact_mid_hz(i));
  EXPECT_NEAR(nm::combustion_noise_level_db(cpl, mids, nm::cao2015_eq_4_1_attenuation()), 80.7782, 2e-3);
}

TEST(CombustionNoise, IsTheEnergySumOfTheWeightedBands) {
  std::vector<double> cpl, levels;
  const auto f = nominal_bands();
  for (std::size_t i = 0; i < nm::kSaBandCount; ++i) {
    cpl.push_back(120.0 + 1.5 * static_cast<double>(i % 7));
    levels.push_back(cpl.back() - 50.0 + kIecA[i]);
  }
  EXPECT_NEAR(nm::combustion_noise_level_db(cpl, f, flat_curve(50.0)), energy_sum(levels), 0.05);
}

TEST(CombustionNoise, ShiftsOneForOneWithTheCurveAndAddsBandsByEnergy) {
  const auto f = nominal_bands();
  std::vector<double> cpl(nm::kSaBandCount, 130.0);
  const double base = nm::combustion_noise_level_db(cpl, f, flat_curve(55.0));
  EXPECT_NEAR(nm::combustion_noise_level_db(cpl, f, flat_curve(58.0)), base - 3.0, 1e-9);
  for (double& c : cpl) c += 7.0;
  EXPECT_NEAR(nm::combustion_noise_level_db(cpl, f, flat_curve(55.0)), base + 7.0, 1e-9);
  // Two equal contributions: +10 lg 2.
  const std::vector<double> one{150.0}, two{150.0, 150.0}, f1{1000.0}, f2{1000.0, 1000.0};
  EXPECT_NEAR(nm::combustion_noise_level_db(two, f2, flat_curve(60.0)) -
                  nm::combustion_noise_level_db(one, f1, flat_curve(60.0)),
              10.0 * std::log10(2.0), 1e-9);
}

TEST(CombustionNoise, SkipsNanBandsAndIsNanWithoutAny) {
  const auto sa = flat_curve(60.0);
  const std::vector<double> f{500.0, 1000.0, 2000.0};
  const double with_gap = nm::combustion_noise_level_db(std::vector<double>{kNaN, 150.0, kNaN}, f, sa);
  EXPECT_NEAR(with_gap, nm::combustion_noise_level_db(std::vector<double>{150.0}, std::vector<double>{1000.0}, sa),
              1e-12);
  EXPECT_TRUE(std::isnan(nm::combustion_noise_level_db(std::vector<double>{kNaN, kNaN, kNaN}, f, sa)));
  EXPECT_TRUE(std::isnan(nm::combustion_noise_level_db(std::vector<double>{}, std::vector<double>{}, sa)));
  // A band with no energy adds nothing.
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_NEAR(nm::combustion_noise_level_db(std::vector<double>{-inf, 150.0, -inf}, f, sa), with_gap, 1e-12);
}

TEST(CombustionNoise, RejectsMismatchedSpansAndBandsTheCurveDoesNotCover) {
  const auto sa = flat_curve(60.0);
  EXPECT_THROW(nm::combustion_noise_level_db(std::vector<double>{150.0, 150.0}, std::vector<double>{1000.0}, sa),
               std::invalid_argument);
  EXPECT_THROW(nm::combustion_noise_level_db(std::vector<double>{150.0}, std::vector<double>{25000.0}, sa),
               std::invalid_argument);
  // An unpublished (NaN) entry: its band cannot be summed, nor can frequencies interpolated from it...
  auto gap = flat_curve(60.0);
  gap.db[5] = kNaN;  // 63 Hz band
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(gap, nm::sa_band_exact_mid_hz(5))));
  EXPECT_TRUE(std::isnan(nm::structure_attenuation_db(gap, 55.0)));
  EXPECT_DOUBLE_EQ(nm::structure_attenuation_db(gap, nm::sa_band_exact_mid_hz(4)), 60.0);
  EXPECT_THROW(nm::combustion_noise_level_db(std::vector<double>{150.0}, std::vector<double>{63.0}, gap),
               std::invalid_argument);
  // ...but a band the caller leaves out (NaN level) is never looked up.
  EXPECT_NO_THROW(
      nm::combustion_noise_level_db(std::vector<double>{kNaN, 150.0}, std::vector<double>{63.0, 1000.0}, gap));
  // Out-of-range frequency of a skipped band is the caller's business too.
  EXPECT_NO_THROW(nm::combustion_noise_level_db(std::vector<double>{kNaN}, std::vector<double>{25000.0}, sa));
}
