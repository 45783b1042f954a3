// Tests of the virtual engine's physics against independent references: slider-crank geometry in closed form,
// the isentropic relations of an adiabatic closed system, the fuel's energy content, the first law, the
// thesis's injection-timing trend, the inverse of the crank kinematics, sample statistics of the cycle
// variation, and a real motored pressure record of the Yanmar L100V.
#include "model/engine_cycle.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <numbers>
#include <span>
#include <sstream>
#include <string>
#include <vector>

namespace nm = noisemon::model;

namespace {

constexpr double kPi = std::numbers::pi;

double trapezoid(std::span<const double> x, std::span<const double> y) {
  double s = 0.0;
  for (std::size_t i = 0; i + 1 < x.size(); ++i) s += 0.5 * (y[i] + y[i + 1]) * (x[i + 1] - x[i]);
  return s;
}

// Brake mean effective pressure of a four-stroke engine: 4 pi T / Vd.
double bmep_pa(double torque_nm, double vd) { return 4.0 * kPi * torque_nm / vd; }

// Cyclic integral of p dV over the whole cycle, sampled through the public pressure interpolation.
double net_work_j(const nm::EngineCycle& ec, double step_deg) {
  const auto& g = ec.params().geometry;
  double w = 0.0;
  for (double th = -360.0; th < 360.0 - 1e-9; th += step_deg) {
    const double p0 = ec.pressure_pa(th), p1 = ec.pressure_pa(th + step_deg);
    w += 0.5 * (p0 + p1) * (g.volume_m3(th + step_deg) - g.volume_m3(th));
  }
  return w;
}

struct PeakAndRise {
  double peak_pa = 0.0;
  double max_rise_pa_per_deg = 0.0;
};
// Peak pressure and maximum rate of rise by central differences of the interpolated pressure.
PeakAndRise peak_and_rise(const nm::EngineCycle& ec) {
  PeakAndRise r;
  const double d = 0.02;
  for (double th = -60.0; th <= 60.0; th += d) {
    r.peak_pa = std::max(r.peak_pa, ec.pressure_pa(th));
    r.max_rise_pa_per_deg = std::max(r.max_rise_pa_per_deg, (ec.pressure_pa(th + d) - ec.pressure_pa(th - d)) / (2 * d));
  }
  return r;
}

const nm::OperatingCondition kIdle{.speed_rpm = 3050.0, .load_nm = 0.0, .soi_deg_btdc = 18.0, .motored = false};
const nm::OperatingCondition kFull{.speed_rpm = 3450.0, .load_nm = 20.0, .soi_deg_btdc = 18.0, .motored = false};

}  // namespace

TEST(EngineGeometry, SliderCrankVolumeMatchesClosedForm) {
  const nm::EngineGeometry g;  // L100V: 86 x 75 mm, CR 21.2
  const double vd = kPi / 4.0 * 0.086 * 0.086 * 0.075;
  const double vc = vd / (21.2 - 1.0);
  EXPECT_NEAR(g.displacement_m3(), vd, 1e-15);
  EXPECT_NEAR(g.displacement_m3(), 435.7e-6, 0.1e-6);  // the data README's 435 cc
  EXPECT_NEAR(g.volume_m3(0.0), vc, 1e-15);
  EXPECT_NEAR(g.volume_m3(720.0), vc, 1e-15);
  EXPECT_NEAR(g.volume_m3(-360.0), vc, 1e-15);
  EXPECT_NEAR(g.volume_m3(180.0), vc + vd, 1e-14);
  EXPECT_NEAR(g.volume_m3(-180.0), vc + vd, 1e-14);
  // At 90 deg the crank pin is level with the axis: travel = l + a - sqrt(l^2 - a^2).
  const double a = 0.0375, l = 0.118;
  EXPECT_NEAR(g.volume_m3(90.0), vc + kPi / 4.0 * 0.086 * 0.086 * (l + a - std::sqrt(l * l - a * a)), 1e-15);
  // dV/dtheta against central differences.
  for (double th = -350.0; th < 360.0; th += 17.3) {
    const double fd = (g.volume_m3(th + 1e-4) - g.volume_m3(th - 1e-4)) / 2e-4;
    EXPECT_NEAR(g.dvolume_m3_per_deg(th), fd, 1e-10 * vd) << th;
  }
}

TEST(EngineCycle, AdiabaticConstantGammaFollowsIsentrope) {
  nm::EngineCycleParams p;
  const double gamma = 1.35;
  p.heat_transfer_scale = 0.0;
  p.cv1_j_kg_k2 = 0.0;
  p.cv0_j_kg_k = p.gas_constant_j_kg_k / (gamma - 1.0);
  nm::EngineCycle ec(p);
  ec.compute({.speed_rpm = 3050.0, .load_nm = 0.0, .soi_deg_btdc = 18.0, .motored = true});
  const auto th = ec.closed_angle_deg();
  const auto pr = ec.closed_pressure_pa();
  const double v_ivc = p.geometry.volume_m3(th[0]);
  EXPECT_NEAR(pr[0], p.intake_pressure_pa, 1e-9 * p.intake_pressure_pa);
  for (std::size_t i = 0; i < th.size(); i += 7) {
    const double expected = p.intake_pressure_pa * std::pow(v_ivc / p.geometry.volume_m3(th[i]), gamma);
    ASSERT_NEAR(pr[i], expected, 1e-8 * expected) << th[i];
  }
  // Between the table nodes too (Hermite interpolation), e.g. near TDC where curvature is largest.
  for (double t = -3.0; t <= 3.0; t += 0.0137) {
    const double expected = p.intake_pressure_pa * std::pow(v_ivc / p.geometry.volume_m3(t), gamma);
    ASSERT_NEAR(ec.pressure_pa(t), expected, 1e-7 * expected) << t;
  }
  // Compression ratio from IVC (30 deg after BDC) to TDC of the L100V: ~20.2; p_max = 1 bar * 20.2^1.35.
  EXPECT_NEAR(ec.summary().peak_pressure_pa, p.intake_pressure_pa * std::pow(v_ivc / p.geometry.clearance_volume_m3(), gamma),
              1e-6 * ec.summary().peak_pressure_pa);
  EXPECT_NEAR(ec.summary().peak_pressure_deg, 0.0, 1e-9);
}

TEST(EngineCycle, AdiabaticVariableGammaKeepsEntropy) {
  // cv = cv0 + cv1 T, ds = 0: cv0 ln T + cv1 T + R ln V = const.
  nm::EngineCycleParams p;
  p.heat_transfer_scale = 0.0;
  nm::EngineCycle ec(p);
  ec.compute({.speed_rpm = 3450.0, .load_nm = 0.0, .soi_deg_btdc = 18.0, .motored = true});
  const auto th = ec.closed_angle_deg();
  const auto temp = ec.closed_temperature_k();
  auto entropy = [&](std::size_t i) {
    return p.cv0_j_kg_k * std::log(temp[i]) + p.cv1_j_kg_k2 * temp[i] + p.gas_constant_j_kg_k * std::log(p.geometry.volume_m3(th[i]));
  };
  const double s0 = entropy(0);
  for (std::size_t i = 0; i < th.size(); i += 11) ASSERT_NEAR(entropy(i), s0, 1e-9 * p.cv0_j_kg_k) << th[i];
}

TEST(EngineCycle, MotoredPeakIsPhysical) {
  nm::EngineCycle ec;
  const auto& p = ec.params();
  ec.compute({.speed_rpm = 3050.0, .load_nm = 0.0, .soi_deg_btdc = 18.0, .motored = true});
  const double ratio = p.geometry.volume_m3(p.ivc_deg) / p.geometry.clearance_volume_m3();
  const auto& s = ec.summary();
  // Between the polytropes n = 1.30 and n = 1.40 (air's gamma at room temperature bounds it from above).
  EXPECT_GT(s.peak_pressure_pa, p.intake_pressure_pa * std::pow(ratio, 1.30));
  EXPECT_LT(s.peak_pressure_pa, p.intake_pressure_pa * std::pow(ratio, 1.40));
  EXPECT_GT(s.peak_pressure_pa, 50e5);
  EXPECT_LT(s.peak_pressure_pa, 65e5);
  // Heat loss: the peak comes slightly before TDC (thermodynamic loss angle) and the loop work is negative.
  EXPECT_LT(s.peak_pressure_deg, 0.0);
  EXPECT_GT(s.peak_pressure_deg, -2.0);
  EXPECT_GT(s.heat_loss_j, 0.0);
  EXPECT_LT(net_work_j(ec, 0.1), 0.0);
  EXPECT_EQ(s.fuel_mass_kg, 0.0);
  EXPECT_TRUE(std::isnan(s.soc_deg));
}

TEST(EngineCycle, IntegratedHeatReleaseEqualsFuelEnergy) {
  nm::EngineCycle ec;
  const auto& p = ec.params();
  for (const auto& op : {kIdle, kFull}) {
    ec.compute(op);
    const auto& s = ec.summary();
    ASSERT_GT(s.fuel_mass_kg, 0.0);
    const double expected = s.fuel_mass_kg * p.fuel_lhv_j_kg * p.combustion_efficiency;
    const double released = trapezoid(ec.closed_angle_deg(), ec.heat_release_rate_j_per_deg());
    EXPECT_NEAR(released, expected, 1e-3 * expected) << op.load_nm;
    EXPECT_NEAR(s.heat_release_j, expected, 1e-6 * expected);
  }
  // Fuel follows the load; idle still burns fuel, motored none.
  const double idle = nm::fuel_mass_per_cycle_kg(p, kIdle);
  const double full = nm::fuel_mass_per_cycle_kg(p, kFull);
  EXPECT_GT(idle, 1e-6);  // > 1 mg
  EXPECT_GT(full, 3.0 * idle);
  EXPECT_LT(full * p.stoichiometric_afr, ec.summary().trapped_mass_kg);  // lean: phi < 1
  auto motored = kFull;
  motored.motored = true;
  EXPECT_EQ(nm::fuel_mass_per_cycle_kg(p, motored), 0.0);
}

TEST(EngineCycle, FirstLawBalancesOverTheClosedPart) {
  // m (u(T_evo) - u(T_ivc)) = Q_released - Q_lost - W, every term integrated here from the traces.
  nm::EngineCycle ec;
  const auto& p = ec.params();
  for (const auto& op : {kIdle, kFull}) {
    ec.compute(op);
    const auto th = ec.closed_angle_deg();
    const auto pr = ec.closed_pressure_pa();
    const auto temp = ec.closed_temperature_k();
    std::vector<double> vol(th.size());
    for (std::size_t i = 0; i < th.size(); ++i) vol[i] = p.geometry.volume_m3(th[i]);
    const double work = trapezoid(vol, pr);
    const double q_in = trapezoid(th, ec.heat_release_rate_j_per_deg());
    const double q_out = trapezoid(th, ec.heat_loss_rate_j_per_deg());
    auto u = [&](double t) { return p.cv0_j_kg_k * t + 0.5 * p.cv1_j_kg_k2 * t * t; };
    const double mass = p.intake_pressure_pa * vol[0] / (p.gas_constant_j_kg_k * p.intake_temperature_k);
    const double du = mass * (u(temp.back()) - u(temp.front()));
    EXPECT_NEAR(du, q_in - q_out - work, 2e-4 * q_in) << op.load_nm;
    // The gas law holds at every node.
    for (std::size_t i = 0; i < th.size(); i += 97)
      ASSERT_NEAR(pr[i] * vol[i], mass * p.gas_constant_j_kg_k * temp[i], 1e-9 * pr[i] * vol[i]);
    // The reported integrals agree with the traces.
    EXPECT_NEAR(ec.summary().closed_work_j, work, 1e-4 * q_in);
    EXPECT_NEAR(ec.summary().heat_loss_j, q_out, 1e-4 * q_in);
    // Wall heat loss of a small DI diesel: a sizeable but minor part of the fuel energy.
    EXPECT_GT(q_out, 0.1 * q_in);
    EXPECT_LT(q_out, 0.5 * q_in);
  }
}

TEST(EngineCycle, FiredCyclesAreSaneForTheLoad) {
  nm::EngineCycle ec;
  const double vd = ec.params().geometry.displacement_m3();
  for (const auto& op : {kIdle, kFull}) {
    for (double soi : {12.0, 18.0, 24.0}) {
      auto o = op;
      o.soi_deg_btdc = soi;
      ec.compute(o);
      const auto pr = peak_and_rise(ec);
      EXPECT_GT(pr.peak_pa, 70e5) << op.load_nm << " " << soi;
      EXPECT_LT(pr.peak_pa, 115e5) << op.load_nm << " " << soi;
      // Net IMEP minus BMEP is the friction the fuel must cover: a plausible FMEP of a small high-speed
      // diesel (0.5 .. 3 bar).
      const double imep = net_work_j(ec, 0.1) / vd;
      EXPECT_NEAR(imep, ec.summary().imep_net_pa, 0.01e5);
      const double fmep = imep - bmep_pa(o.load_nm, vd);
      EXPECT_GT(fmep, 0.5e5) << op.load_nm << " " << soi;
      EXPECT_LT(fmep, 3.0e5) << op.load_nm << " " << soi;
      // Ignition delay of a few tenths of a millisecond; combustion starts before TDC for these timings.
      const double delay_ms = 1e3 * ec.summary().ignition_delay_deg / (6.0 * o.speed_rpm);
      EXPECT_GT(delay_ms, 0.2);
      EXPECT_LT(delay_ms, 1.2);
    }
  }
}

TEST(EngineCycle, EarlierInjectionIsLouder) {
  // Thesis 3.3: earlier injection -> longer delay -> more premixed burn -> faster pressure rise.
  nm::EngineCycle ec;
  for (const auto& op : {kIdle, kFull}) {
    PeakAndRise prev{};
    double prev_delay = 0.0, prev_beta = 0.0;
    for (double soi = 12.0; soi <= 24.0; soi += 3.0) {
      auto o = op;
      o.soi_deg_btdc = soi;
      ec.compute(o);
      const auto pr = peak_and_rise(ec);
      EXPECT_GT(pr.peak_pa, prev.peak_pa) << op.load_nm << " soi " << soi;
      EXPECT_GT(pr.max_rise_pa_per_deg, prev.max_rise_pa_per_deg) << op.load_nm << " soi " << soi;
      EXPECT_GT(ec.summary().ignition_delay_deg, prev_delay);
      EXPECT_GE(ec.summary().premixed_fraction, prev_beta);
      prev = pr;
      prev_delay = ec.summary().ignition_delay_deg;
      prev_beta = ec.summary().premixed_fraction;
    }
  }
}

TEST(EngineCycle, PressureIsContinuousAcrossValveEventsAndCycles) {
  nm::EngineCycle ec;
  ec.compute(kFull);
  const auto& p = ec.params();
  EXPECT_DOUBLE_EQ(ec.pressure_pa(-360.0), p.intake_pressure_pa);
  EXPECT_NEAR(ec.pressure_pa(360.0), p.intake_pressure_pa, 1e-9);
  // Value and slope (one-sided differences on each side) continuous at EVO and at the start of the
  // exhaust->intake blend; value continuous at IVC.
  const double d = 1e-3;
  for (double at : {p.evo_deg, 340.0}) {
    EXPECT_NEAR(ec.pressure_pa(at - 1e-7), ec.pressure_pa(at + 1e-7), 1e-3) << at;
    const double left = (ec.pressure_pa(at) - ec.pressure_pa(at - d)) / d;
    const double right = (ec.pressure_pa(at + d) - ec.pressure_pa(at)) / d;
    EXPECT_NEAR(left, right, 0.01 * std::abs(left) + 20.0) << at;
  }
  EXPECT_NEAR(ec.pressure_pa(p.ivc_deg - 1e-7), ec.pressure_pa(p.ivc_deg + 1e-7), 1e-3);
  // Blowdown reaches the exhaust pressure before the exhaust stroke ends.
  EXPECT_NEAR(ec.pressure_pa(300.0), p.exhaust_pressure_pa, 1.0);
}

TEST(CrankKinematics, InverseAndSpeedProfile) {
  const double rpm = 3450.0, eps = 0.01;
  const nm::CrankKinematics k(rpm, eps);
  EXPECT_DOUBLE_EQ(k.theta_deg(0.0), -360.0);
  for (double th = -360.0; th < 2000.0; th += 3.7) {
    const double t = k.time_s(th);
    ASSERT_NEAR(k.theta_deg(t), th, 1e-9) << th;
  }
  for (double t = 0.0; t < 0.2; t += 0.00123) ASSERT_NEAR(k.time_s(k.theta_deg(t)), t, 1e-12);
  // Exactly 720 deg per cycle period, cycle boundaries at the mean angle.
  const double period = 120.0 / rpm;
  EXPECT_NEAR(k.time_s(360.0), period, 1e-12);
  EXPECT_NEAR(k.theta_deg(0.37 + period) - k.theta_deg(0.37), 720.0, 1e-9);
  // Slowest at firing TDC, fastest at gas-exchange TDC; the derivative of theta(t) is the speed.
  EXPECT_NEAR(k.speed_rpm(k.time_s(0.0)), rpm * (1.0 - eps), 1e-9);
  EXPECT_NEAR(k.speed_rpm(k.time_s(360.0)), rpm * (1.0 + eps), 1e-9);
  for (double t = 0.001; t < 0.05; t += 0.0031) {
    const double dt = 1e-6;
    const double deg_per_s = (k.theta_deg(t + dt) - k.theta_deg(t - dt)) / (2 * dt);
    EXPECT_NEAR(deg_per_s / 6.0, k.speed_rpm(t), 1e-5 * rpm);
  }
  // Cycle bookkeeping: cycle k spans [720 k - 360, 720 k + 360).
  EXPECT_EQ(nm::CrankKinematics::cycle_index(-360.0), 0);
  EXPECT_EQ(nm::CrankKinematics::cycle_index(359.999), 0);
  EXPECT_EQ(nm::CrankKinematics::cycle_index(360.0), 1);
  EXPECT_EQ(nm::CrankKinematics::cycle_index(-360.001), -1);
  EXPECT_DOUBLE_EQ(nm::CrankKinematics::cycle_angle(360.0), -360.0);
  EXPECT_NEAR(nm::CrankKinematics::cycle_angle(1450.5), 10.5, 1e-9);
  EXPECT_NEAR(nm::CrankKinematics::cycle_angle(-370.0), 350.0, 1e-9);
}

TEST(CycleVariation, DrawStatistics) {
  const double sigma = 0.03;
  const int n = 20000;
  std::vector<double> a(n), b(n);
  for (int i = 0; i < n; ++i) {
    const auto v = nm::draw_cycle_variation(7, i - n / 2, sigma);
    a[i] = v.heat_release_scale - 1.0;
    b[i] = v.ignition_delay_scale - 1.0;
  }
  auto mean = [](const std::vector<double>& x) {
    double s = 0;
    for (double v : x) s += v;
    return s / static_cast<double>(x.size());
  };
  auto cov = [&](const std::vector<double>& x, std::size_t xo, const std::vector<double>& y, std::size_t yo) {
    const double mx = mean(x), my = mean(y);
    double s = 0;
    const std::size_t m = x.size() - std::max(xo, yo);
    for (std::size_t i = 0; i < m; ++i) s += (x[i + xo] - mx) * (y[i + yo] - my);
    return s / static_cast<double>(m);
  };
  const double se = sigma / std::sqrt(static_cast<double>(n));
  EXPECT_NEAR(mean(a), 0.0, 4 * se);
  EXPECT_NEAR(mean(b), 0.0, 4 * se);
  EXPECT_NEAR(std::sqrt(cov(a, 0, a, 0)), sigma, 0.03 * sigma);
  EXPECT_NEAR(std::sqrt(cov(b, 0, b, 0)), sigma, 0.03 * sigma);
  // Independent between the two scales and from cycle to cycle (|r| < 4 / sqrt(n)).
  const double var = sigma * sigma, lim = 4.0 / std::sqrt(static_cast<double>(n));
  EXPECT_LT(std::abs(cov(a, 0, b, 0)) / var, lim);
  EXPECT_LT(std::abs(cov(a, 0, a, 1)) / var, lim);
  EXPECT_LT(std::abs(cov(b, 0, b, 1)) / var, lim);
  // Deterministic in (seed, cycle), different for another seed.
  const auto x = nm::draw_cycle_variation(7, 123, sigma), y = nm::draw_cycle_variation(7, 123, sigma);
  EXPECT_EQ(x.heat_release_scale, y.heat_release_scale);
  EXPECT_EQ(x.ignition_delay_scale, y.ignition_delay_scale);
  EXPECT_NE(nm::draw_cycle_variation(8, 123, sigma).heat_release_scale, x.heat_release_scale);
  EXPECT_EQ(nm::draw_cycle_variation(7, 123, 0.0).heat_release_scale, 1.0);
}

TEST(CycleVariation, ScalesPeakPressureFromCycleToCycle) {
  nm::EngineCycle ec;
  const int n = 60;
  double s = 0, s2 = 0;
  for (int i = 0; i < n; ++i) {
    ec.compute(kIdle, nm::draw_cycle_variation(3, i, 0.03));
    const double pk = ec.summary().peak_pressure_pa;
    s += pk;
    s2 += pk * pk;
  }
  const double mean = s / n, sd = std::sqrt(s2 / n - mean * mean);
  ec.compute(kIdle);
  // The mean stays at the nominal cycle's, and cycles differ by a percent or so (peak pressure
  // coefficient of variation of a diesel: ~0.5 .. 3 %).
  EXPECT_NEAR(mean, ec.summary().peak_pressure_pa, 0.01 * mean);
  EXPECT_GT(sd / mean, 0.002);
  EXPECT_LT(sd / mean, 0.03);
}

TEST(EngineCycle, MotoredCurveAgreesWithRealYanmarRecord) {
  const std::string path = std::string(NOISEMON_SHARED_DIR) + "/data/real/yanmar_l100v_motored.txt";
  std::ifstream in(path);
  if (!in) {
    const char* ci = std::getenv("CI");
    if (ci && std::string(ci) == "true") FAIL() << "missing " << path;
    GTEST_SKIP() << "reference data not found: " << path;
  }
  // Column 1 crank angle (deg), then one column per cycle (bar abs); the first row is a pegging value.
  std::vector<double> angle, mean_bar;
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    if (first) {
      first = false;
      continue;
    }
    std::istringstream ss(line);
    double a, v, sum = 0;
    int n = 0;
    if (!(ss >> a)) continue;
    while (ss >> v) {
      sum += v;
      ++n;
    }
    angle.push_back(a);
    mean_bar.push_back(sum / n);
  }
  ASSERT_GT(angle.size(), 3000u);
  std::size_t ipk = 0;
  for (std::size_t i = 0; i < angle.size(); ++i)
    if (mean_bar[i] > mean_bar[ipk]) ipk = i;

  nm::EngineCycle ec;  // the L100V defaults, nominal CR 21.2
  ec.compute({.speed_rpm = 1800.0, .load_nm = 0.0, .soi_deg_btdc = 0.0, .motored = true});
  // Compression branch (-120 .. -30 deg), where the record is free of the TDC losses: within 15 %.
  for (std::size_t i = 0; i < angle.size(); ++i) {
    if (angle[i] < -120.0 || angle[i] > -30.0) continue;
    const double model_bar = 1e-5 * ec.pressure_pa(angle[i]);
    EXPECT_NEAR(model_bar, mean_bar[i], 0.15 * mean_bar[i]) << angle[i];
  }
  // Peak: the record (about 52 bar at -2.6 deg) sits below any loss-free single zone at the nominal CR 21.2 (and
  // is lopsided: 29.1 bar at -20 deg vs 21.0 bar at +20 deg), i.e. it carries blow-by, crevice and
  // transducer-passage volume this model leaves out. The model may exceed it, but by no more than 25 %.
  const double model_peak_bar = 1e-5 * ec.summary().peak_pressure_pa;
  std::printf("motored peak: record %.1f bar at %.1f deg, model %.1f bar at %.1f deg (ratio %.3f)\n", mean_bar[ipk],
              angle[ipk], model_peak_bar, ec.summary().peak_pressure_deg, model_peak_bar / mean_bar[ipk]);
  EXPECT_GT(model_peak_bar, mean_bar[ipk]);
  EXPECT_LT(model_peak_bar, 1.25 * mean_bar[ipk]);
  EXPECT_NEAR(ec.summary().peak_pressure_deg, angle[ipk], 4.0);
}
