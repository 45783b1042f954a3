// The independent cell's block in the time domain (see cell_block.hpp).
#include "cell_block.hpp"

#include <cmath>
#include <numbers>

namespace indep {
namespace {

constexpr std::size_t kOversample = 4;  // fine samples per input sample; one RK4 step spans two of them

struct State {
  double z = 0, v = 0;
};

State derivative(const State& x, double u, const Structure& s, const Nonlinearity& nl) {
  return {x.v, u - block_force(x.z, x.v, s, nl)};
}

State step(const State& x, double u0, double u_mid, double u1, double h, const Structure& s, const Nonlinearity& nl) {
  const State k1 = derivative(x, u0, s, nl);
  const State k2 = derivative({x.z + 0.5 * h * k1.z, x.v + 0.5 * h * k1.v}, u_mid, s, nl);
  const State k3 = derivative({x.z + 0.5 * h * k2.z, x.v + 0.5 * h * k2.v}, u_mid, s, nl);
  const State k4 = derivative({x.z + h * k3.z, x.v + h * k3.v}, u1, s, nl);
  return {x.z + h / 6 * (k1.z + 2 * k2.z + 2 * k3.z + k4.z), x.v + h / 6 * (k1.v + 2 * k2.v + 2 * k3.v + k4.v)};
}

}  // namespace

double linear_damping_per_kg(const Structure& s) { return 2 * s.zeta * 2 * kPi * s.fn_hz; }

double block_force(double z, double v, const Structure& s, const Nonlinearity& nl) {
  const double wn = 2 * kPi * s.fn_hz;
  double f = wn * wn * z + linear_damping_per_kg(s) * v + nl.quadratic_damping * v * std::abs(v);
  if (nl.stop_at_m > 0 && std::abs(z) > nl.stop_at_m)
    f += nl.stop_ratio * wn * wn * std::copysign(std::abs(z) - nl.stop_at_m, z);
  return f;
}

BlockMotion block_motion(const std::vector<double>& u, double period_s, const Structure& s, const Nonlinearity& nl) {
  const std::size_t fine_n = kOversample * u.size(), steps = fine_n / 2;
  const std::vector<double> fine = radiate(u, fine_n, period_s, [](double) { return std::complex<double>(1.0, 0.0); });
  const double h = period_s / static_cast<double>(steps), wb = 2 * kPi * s.fb_hz;
  BlockMotion m;
  m.z_m.resize(steps), m.v_m_per_s.resize(steps), m.y_pa.resize(steps);
  State x;
  for (int pass = 0; pass < 2; ++pass)
    for (std::size_t i = 0; i < steps; ++i) {
      if (pass == 1) m.z_m[i] = x.z, m.v_m_per_s[i] = x.v, m.y_pa[i] = s.ka * (x.v + wb * x.z);
      x = step(x, fine[2 * i], fine[2 * i + 1], fine[(2 * i + 2) % fine_n], h, s, nl);
    }
  return m;
}

}  // namespace indep
