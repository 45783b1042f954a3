// Block-model parameters against the thesis: Table 4.1 presets, eq. 4.1 and its eq. 4.8 mapping.
#include "dsp/math_constants.hpp"
#include "model/block_params.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <string>

namespace noisemon::model {
namespace {

using noisemon::kPi;

// Eq. 4.1 constants as printed in the thesis (sec. 4.3.1).
constexpr double kKa = 11.885;
constexpr double kWb = 628.319;  // 2 pi 100 rad/s
constexpr double kZeta = 0.35;
constexpr double kWn = 31415.927;  // 2 pi 5000 rad/s

// |eq. 4.1| and its phase written out in real arithmetic (not through the library's complex form).
double eq41_magnitude(double f) {
  const double w = 2 * kPi * f;
  return kKa * std::hypot(w, kWb) / std::hypot(kWn * kWn - w * w, 2 * kZeta * kWn * w);
}
double eq41_phase(double f) {
  const double w = 2 * kPi * f;
  return std::atan2(w, kWb) - std::atan2(2 * kZeta * kWn * w, kWn * kWn - w * w);
}

TEST(BlockParams, PresetsAreTable41) {
  struct Row {
    const char* name;
    double k1, k3, b1, b3;
  };
  const Row rows[] = {{"linear", 9.87e8, 0, 2.20e4, 0},
                      {"nl_damper", 9.87e8, 0, 7.00e3, 2.00e3},
                      {"nl_spring_damper", 8.00e8, 1.00e13, 7.00e3, 2.00e3},
                      {"nl_spring_damper_opt", 8.37e8, 1.00e13, 6.00e3, 4.00e3}};
  for (const auto& r : rows) {
    SCOPED_TRACE(r.name);
    const BlockParams p = preset(r.name);
    EXPECT_DOUBLE_EQ(p.m, 1.0);
    EXPECT_DOUBLE_EQ(p.k1, r.k1);
    EXPECT_DOUBLE_EQ(p.k3, r.k3);
    EXPECT_DOUBLE_EQ(p.b1, r.b1);
    EXPECT_DOUBLE_EQ(p.b3, r.b3);
    EXPECT_DOUBLE_EQ(p.c1, 11.885);   // eq. 4.9: C1 = m ka
    EXPECT_DOUBLE_EQ(p.c0, 7467.57);  // eq. 4.9: C0 = C1 wb
    EXPECT_EQ(p.is_linear(), std::string(r.name) == "linear");
  }
  const auto names = preset_names();
  ASSERT_EQ(names.size(), 4u);
  for (const auto& r : rows) EXPECT_NE(std::find(names.begin(), names.end(), r.name), names.end()) << r.name;
}

TEST(BlockParams, UnknownPresetNamesItAndTheValidOnes) {
  try {
    preset("nl_spring");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'nl_spring'"), std::string::npos) << msg;
    for (const auto& n : preset_names()) EXPECT_NE(msg.find(n), std::string::npos) << msg;
  }
}

TEST(BlockParams, ThesisTransferFunctionIsEq41) {
  for (double f = 1.0; f < 25000.0; f *= 1.07) {
    const auto h = thesis_tf_4_1(f);
    EXPECT_NEAR(std::abs(h) / eq41_magnitude(f), 1.0, 1e-6) << f;
    EXPECT_NEAR(std::remainder(std::arg(h) - eq41_phase(f), 2 * kPi), 0.0, 1e-6) << f;
  }
  // DC gain ka wb / wn^2 (the printed constants are rounded to 1e-6 relative).
  EXPECT_NEAR(std::abs(thesis_tf_4_1(0.0)) / (kKa * kWb / (kWn * kWn)), 1.0, 1e-6);
}

// Fig. 4.4: the attenuation (-20 log10 |Y/U|, no A-weighting) has its minimum near 5 kHz, about 65 dB.
TEST(BlockParams, Eq41AttenuationMinimumIsAbout65dBNear5kHz) {
  double best_att = 1e9, best_f = 0;
  for (double f = 20; f <= 20000; f *= 1.001) {
    const double att = -20 * std::log10(std::abs(thesis_tf_4_1(f)));
    if (att < best_att) {
      best_att = att;
      best_f = f;
    }
  }
  EXPECT_NEAR(best_f, 5000.0, 250.0);
  EXPECT_NEAR(best_att, 65.0, 1.0);
  // Around the minimum the slope approaches 20 dB/decade on both sides (sec. 4.3.1).
  const double att_500 = -20 * std::log10(std::abs(thesis_tf_4_1(500)));
  const double att_1000 = -20 * std::log10(std::abs(thesis_tf_4_1(1000)));
  EXPECT_NEAR(att_500 - att_1000, 20 * std::log10(2.0), 1.5);
}

// The Table 4.1 linear preset is eq. 4.1 through the eq. 4.8 mapping (k1 = m wn^2 etc., rounded to
// three digits in the thesis), so the two responses agree to the rounding.
TEST(BlockParams, LinearPresetResponseIsEq41) {
  const BlockParams p = preset("linear");
  double worst = 0;
  for (double f = 20; f <= 20000; f *= 1.02) {
    const auto h = linear_response(p, f);
    const auto ref = thesis_tf_4_1(f);
    worst = std::max(worst, std::abs(h - ref) / std::abs(ref));
  }
  EXPECT_LT(worst, 1e-3);
}

// linear_response against the mechanical-impedance form: velocity / force = 1 / (m s + b1 + k1 / s),
// y = (C1 + C0 / s) velocity.
TEST(BlockParams, LinearResponseIsTheMassSpringDamperImpedance) {
  for (const auto& name : preset_names()) {
    const BlockParams p = preset(name);
    for (double f = 10; f <= 20000; f *= 1.3) {
      const std::complex<double> s(0, 2 * kPi * f);
      const auto mobility = 1.0 / (p.m * s + p.b1 + p.k1 / s);
      const auto ref = (p.c1 + p.c0 / s) * mobility;
      EXPECT_NEAR(std::abs(linear_response(p, f) - ref) / std::abs(ref), 0.0, 1e-12) << name << " " << f;
    }
  }
}

}  // namespace
}  // namespace noisemon::model
