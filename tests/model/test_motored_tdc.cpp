// Thermodynamic TDC (model/motored_tdc.hpp) on motored cycles made here by a closed-cylinder energy balance that
// shares nothing with the code under test: its own slider-crank volume, Newton cooling to the walls and blow-by
// through the rings, integrated in crank angle (RK4) from intake valve closing to exhaust valve opening. Its peak lies
// before its TDC by a loss angle that comes out of the physics, not out of a number typed in. The recording's scale
// runs early by a known offset, with per-sample noise and a pegging error per cycle as the Yanmar tables have.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <vector>

#include "model/motored_tdc.hpp"

namespace noisemon::model {
namespace {

constexpr double kBore = 0.086, kStroke = 0.075, kRod = 0.118, kCr = 21.2, kRpm = 1800.0;
constexpr double kR = 287.0, kCv = 718.0;

double volume(double theta_deg) {
  const double a = kStroke / 2.0, th = theta_deg * std::numbers::pi / 180.0;
  const double area = std::numbers::pi * kBore * kBore / 4.0, vd = area * kStroke;
  const double s = a + kRod - (a * std::cos(th) + std::sqrt(kRod * kRod - a * a * std::sin(th) * std::sin(th)));
  return vd / (kCr - 1.0) + area * s;
}

double wall_area(double theta_deg) {
  const double area = std::numbers::pi * kBore * kBore / 4.0;
  return 2.0 * area + std::numbers::pi * kBore * (volume(theta_deg) / area);
}

// d/dtheta of (T, m): m cv dT = dQ - p dV + R T dm (the leaking gas takes its enthalpy), per degree.
struct Gas {
  double h_w_m2k, blowby_kg_per_s_pa, wall_k;
  std::array<double, 2> rate(double theta, double T, double m) const {
    const double dt_per_deg = 1.0 / (6.0 * kRpm), V = volume(theta);
    const double p = m * kR * T / V, dV = (volume(theta + 1e-4) - volume(theta - 1e-4)) / 2e-4;
    const double dQ = -h_w_m2k * wall_area(theta) * (T - wall_k) * dt_per_deg;
    const double dm = -blowby_kg_per_s_pa * std::max(0.0, p - 1e5) * dt_per_deg;
    return {(dQ - p * dV + kR * T * dm) / (m * kCv), dm};
  }
};

// Pressure (bar) on the true scale, every step_deg from -150 to 130 deg.
std::vector<double> motored_cycle(const Gas& g, double step_deg) {
  const int sub = 20;
  const double h = step_deg / sub, T0 = 330.0;
  double theta = -150.0, T = T0, m = 1.0e5 * volume(theta) / (kR * T0);
  std::vector<double> out;
  while (theta <= 130.0 + 1e-9) {
    out.push_back(m * kR * T / volume(theta) / 1e5);
    for (int k = 0; k < sub; ++k) {
      const auto k1 = g.rate(theta, T, m);
      const auto k2 = g.rate(theta + h / 2, T + h / 2 * k1[0], m + h / 2 * k1[1]);
      const auto k3 = g.rate(theta + h / 2, T + h / 2 * k2[0], m + h / 2 * k2[1]);
      const auto k4 = g.rate(theta + h, T + h * k3[0], m + h * k3[1]);
      T += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]);
      m += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]);
      theta += h;
    }
  }
  return out;
}

// The dense cycle's own peak (a 0.01 deg grid's maximum, the vertex through it and its neighbours), true scale.
double true_peak_deg(const Gas& g) {
  const double step = 0.01;
  const std::vector<double> p = motored_cycle(g, step);
  std::size_t top = 1;
  for (std::size_t i = 1; i + 1 < p.size(); ++i)
    if (p[i] > p[top]) top = i;
  const double curvature = p[top - 1] - 2 * p[top] + p[top + 1];
  return -150.0 + step * (static_cast<double>(top) - 0.5 * (p[top + 1] - p[top - 1]) / curvature);
}

// Woschni-like motored heat transfer near TDC, a few per cent of the charge past the rings; and twice the losses.
const Gas kGas{1000.0, 5.0e-11, 420.0};
const Gas kLossyGas{2500.0, 1.0e-10, 420.0};

TEST(MotoredTdc, FindsTheTdcOfAnEnergyBalanceRecordedOnAnEarlyScale) {
  for (const Gas& gas : {kGas, kLossyGas}) {
    const double step = 0.2, early = 1.9;  // the record's 0 lies 1.9 deg before the true TDC
    const std::vector<double> clean = motored_cycle(gas, step);
    std::mt19937 rng(7);
    std::normal_distribution<double> sample_noise(0.0, 0.15), pegging(0.0, 0.15);
    std::vector<std::vector<double>> cycles(60, clean);
    for (std::vector<double>& c : cycles) {
      const double offset = pegging(rng);
      for (double& p : c) p += offset + sample_noise(rng);
    }
    // Recorded angle = true angle - early: the grid starts at -150 - early on the record's scale.
    const double peak_true = true_peak_deg(gas), loss = -peak_true;
    std::printf("energy balance: peak %.3f deg before TDC (the loss angle it makes)\n", loss);
    ASSERT_GT(loss, 0.2);
    ASSERT_LT(loss, 2.0);
    const MotoredTdc r = motored_tdc(cycles, -150.0 - early, step, EngineGeometry{}, loss);
    std::printf(
        "peak %.3f deg (truth %.3f), TDC by loss angle %.3f, by polytropic fit %.3f (truth %.3f), n %.3f, "
        "rms %.4f\n",
        r.peak_deg, peak_true - early, r.tdc_by_loss_angle_deg, r.tdc_by_polytropic_deg, -early, r.polytropic_exponent,
        r.fit_rms);
    EXPECT_EQ(r.cycles, 60);
    EXPECT_NEAR(r.peak_deg, peak_true - early, 0.05);
    EXPECT_NEAR(r.tdc_by_loss_angle_deg, -early, 0.05);
    EXPECT_NEAR(r.tdc_by_polytropic_deg, -early, 0.25);
    EXPECT_GT(r.polytropic_exponent, 1.25);
    EXPECT_LT(r.polytropic_exponent, 1.41);  // air's gamma (cv 718) bounds it
  }
}

TEST(MotoredTdc, ClearErrorsForWhatCannotGiveATdc) {
  const std::vector<double> clean = motored_cycle(kGas, 0.5);
  const std::vector<std::vector<double>> one{clean};
  const auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  EXPECT_NE(message([&] { motored_tdc({}, -150, 0.5, EngineGeometry{}); }).find("no motored cycles"),
            std::string::npos);
  EXPECT_NE(message([&] { motored_tdc(one, -150, 0.5, EngineGeometry{}, 5.0); }).find("loss angle 5"),
            std::string::npos);
  // A fired cycle: a combustion bump that puts the peak 12 deg after TDC.
  std::vector<std::vector<double>> fired{clean};
  for (std::size_t i = 0; i < fired[0].size(); ++i) {
    const double theta = -150.0 + 0.5 * static_cast<double>(i);
    fired[0][i] += 80.0 * std::exp(-0.5 * std::pow((theta - 12.0) / 6.0, 2));
  }
  EXPECT_NE(message([&] { motored_tdc(fired, -150, 0.5, EngineGeometry{}); }).find("not a motored cycle"),
            std::string::npos);
  // A fired cycle whose peak lies within 10 deg of TDC (the Yanmar fired record's: 9 deg): its curve is no polytropic.
  for (std::size_t i = 0; i < fired[0].size(); ++i) {
    const double theta = -150.0 + 0.5 * static_cast<double>(i);
    fired[0][i] = clean[i] + 30.0 * std::exp(-0.5 * std::pow((theta - 6.0) / 8.0, 2));
  }
  EXPECT_NE(message([&] { motored_tdc(fired, -150, 0.5, EngineGeometry{}); }).find("not a motored cycle"),
            std::string::npos);
  std::vector<std::vector<double>> ragged{clean, std::vector<double>(clean.begin(), clean.end() - 1)};
  EXPECT_NE(message([&] { motored_tdc(ragged, -150, 0.5, EngineGeometry{}); }).find("different lengths"),
            std::string::npos);
}

}  // namespace
}  // namespace noisemon::model
