#include "dsp/fir_design.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace noisemon::dsp::fir {

double sinc(double x) {
  if (x == 0.0) return 1.0;
  const double px = std::numbers::pi * x;
  return std::sin(px) / px;
}

double kaiser_beta(double attenuation_db) {
  const double a = attenuation_db;
  if (a > 50.0) return 0.1102 * (a - 8.7);
  if (a >= 21.0) return 0.5842 * std::pow(a - 21.0, 0.4) + 0.07886 * (a - 21.0);
  return 0.0;
}

std::size_t kaiser_half_length(double attenuation_db, double transition_width) {
  if (!(transition_width > 0.0 && transition_width < 0.5))
    throw std::invalid_argument("kaiser_half_length: transition width must be in (0, 0.5) cycles/sample");
  // Filter order M = (A - 8) / (2.285 * 2 pi * width); 2J >= M.
  const double order = (attenuation_db - 8.0) / (2.285 * 2.0 * std::numbers::pi * transition_width);
  return static_cast<std::size_t>(std::ceil(order / 2.0));
}

double bessel_i0(double x) {
  // Power series sum_k ((x/2)^k / k!)^2: all terms positive, converges fast for the betas used here (< 20).
  const double q = 0.25 * x * x;
  double term = 1.0, sum = 1.0;
  for (int k = 1; k < 500 && term > 1e-17 * sum; ++k) {
    term *= q / (static_cast<double>(k) * static_cast<double>(k));
    sum += term;
  }
  return sum;
}

double kaiser_window(double x, double beta) {
  if (x < -1.0 || x > 1.0) return 0.0;
  return bessel_i0(beta * std::sqrt(1.0 - x * x)) / bessel_i0(beta);
}

std::vector<double> kaiser_lowpass(std::size_t half_length, double cutoff, double beta) {
  if (!(cutoff > 0.0 && cutoff < 0.5)) throw std::invalid_argument("kaiser_lowpass: cutoff must be in (0, 0.5)");
  const auto j = static_cast<double>(half_length);
  std::vector<double> h(2 * half_length + 1);
  for (std::size_t i = 0; i < h.size(); ++i) {
    const double n = static_cast<double>(i) - j;
    const double x = half_length == 0 ? 0.0 : n / j;
    h[i] = 2.0 * cutoff * sinc(2.0 * cutoff * n) * kaiser_window(x, beta);
  }
  return h;
}

}  // namespace noisemon::dsp::fir
