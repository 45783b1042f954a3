// The independent cell's block in the time domain: eq. 4.1 written as the mass-spring-damper it is (m = 1 kg,
// k1 = wn^2, b1 = 2 zeta wn, y = ka (z' + wb z)), with nonlinearities the diagnosis's candidates do not have exactly:
//   a stop          beyond |z| = stop_at_m the block meets a second spring of stop_ratio * k1 (a piecewise-linear,
//                   symmetric hardening: a joint closing, a cover meeting its stop), where the candidate is k3 z^3
//   quadratic drag  a damping force quadratic_damping * z' |z'| (fluid-like), where the candidate is b3 z'^3
// Integrated by the classical fourth-order Runge-Kutta method on the input band-limited-interpolated to four times
// its rate (the midpoints of every step are samples of the band-limited input, not holds: the sampling trap of
// docs/accuracy.md), over one period of a periodic input, run twice so that the kept second pass starts from its own
// end state. Shares nothing with model/ (its integrator, its presets) or with the frequency-domain synthesis it is
// checked against.
#pragma once

#include <vector>

#include "cell_synth.hpp"

namespace indep {

// The block's motion and output over one period, at twice the input's rate (2n samples for n input samples).
struct BlockMotion {
  std::vector<double> z_m, v_m_per_s, y_pa;
};

// u: one period of n uniform samples of the input (Pa, its mean removed by the caller), period_s long.
[[nodiscard]] BlockMotion block_motion(const std::vector<double>& u, double period_s, const Structure& s,
                                       const Nonlinearity& nl);

// The linear block's damping per kg, b1 = 2 zeta wn (N s/m per kg).
[[nodiscard]] double linear_damping_per_kg(const Structure& s);

// The restoring and damping forces per kg (N/kg) at displacement z and velocity v.
[[nodiscard]] double block_force(double z, double v, const Structure& s, const Nonlinearity& nl);

}  // namespace indep
