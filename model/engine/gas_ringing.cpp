#include "model/engine/gas_ringing.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace noisemon::model::engine {

namespace {

constexpr double kTaperDeg = 20.0;  // raised-cosine end before EVO

// Normalised premixed Wiebe rate (peak 1) at x = (theta - soc) / duration.
double premixed_shape_at(double x, double a, double m, double peak) {
  if (x <= 0.0) return 0.0;
  const double xm = std::pow(x, m);
  const double e = a * xm * x;
  return e < 50.0 ? a * (m + 1.0) * xm * std::exp(-e) / peak : 0.0;
}

}  // namespace

double draper_frequency_hz(double alpha, double speed_of_sound_m_s, double bore_m) {
  return speed_of_sound_m_s * alpha / (kPi * bore_m);
}

double gas_speed_of_sound_m_s(double temperature_k, double gas_constant_j_kg_k, double cv0_j_kg_k, double cv1_j_kg_k2) {
  const double cv = cv0_j_kg_k + cv1_j_kg_k2 * temperature_k;
  const double gamma = (cv + gas_constant_j_kg_k) / cv;
  return std::sqrt(gamma * gas_constant_j_kg_k * temperature_k);
}

double premixed_peak_fraction(double wiebe_a, double shape) {
  return std::pow(shape / ((shape + 1.0) * wiebe_a), 1.0 / (shape + 1.0));
}

double add_gas_ringing(const GasRingingParams& params, const RingingInput& in, std::span<double> p,
                       std::span<double> dp, std::span<double> scratch) {
  const std::size_t n = in.angle_deg.size();
  if (!params.active() || !(in.premixed_j > 0.0) || n < 2 || !(in.deg_per_s > 0.0)) return 0.0;
  if (p.size() < n || dp.size() < n || scratch.size() < 2 * n)
    throw std::invalid_argument("add_gas_ringing: spans too short");
  const double h = in.angle_deg[1] - in.angle_deg[0];
  const double a = in.wiebe_a, m = in.premixed_shape, dur = in.premixed_duration_deg;
  const double xs = premixed_peak_fraction(a, m);
  const double shape_peak = a * (m + 1.0) * std::pow(xs, m) * std::exp(-a * std::pow(xs, m + 1.0));
  // Amplitude: gain times the pressure-rise rate of the premixed burn at its peak, dp/dt = (gamma - 1) / V dQ/dt.
  const double theta_pk = in.soc_deg + xs * dur;
  const auto node =
      static_cast<std::size_t>(std::clamp(std::lround((theta_pk - in.angle_deg[0]) / h), 0L, static_cast<long>(n - 1)));
  const double t_pk = in.temperature_k[node];
  const double cv = in.cv0 + in.cv1 * t_pk;
  const double qdot_pk = in.premixed_j / dur * shape_peak * in.deg_per_s;  // J/s
  const double amp = params.gain_s * (in.gas_constant / cv) / in.volume_at_peak_m3 * qdot_pk;
  // Envelope: de/dtheta = (w - e) / (tau * deg_per_s), trapezoid (the step is ~1e-3 of tau), then peak 1.
  const double r = h / (params.decay_s * in.deg_per_s);
  const std::span<double> w = scratch.first(n), e = scratch.subspan(n, n);
  e[0] = 0.0;
  for (std::size_t i = 0; i < n; ++i) w[i] = premixed_shape_at((in.angle_deg[i] - in.soc_deg) / dur, a, m, shape_peak);
  double e_max = 0.0;
  for (std::size_t i = 1; i < n; ++i) {
    e[i] = (e[i - 1] * (1.0 - 0.5 * r) + 0.5 * r * (w[i - 1] + w[i])) / (1.0 + 0.5 * r);
    e_max = std::max(e_max, e[i]);
  }
  if (!(e_max > 0.0)) return 0.0;
  const double evo = in.angle_deg[n - 1];
  std::array<double, kRingingModes> phase = in.phase_rad;
  std::array<double, kRingingModes> rate_prev{};  // dphi/dtheta at the previous node
  for (std::size_t i = 0; i < n; ++i) {
    const double th = in.angle_deg[i];
    const double c = gas_speed_of_sound_m_s(in.temperature_k[i], in.gas_constant, in.cv0, in.cv1);
    // Taper s(theta) over the last kTaperDeg before EVO.
    const double u = std::clamp((evo - th) / kTaperDeg, 0.0, 1.0);
    const double s = 0.5 - 0.5 * std::cos(kPi * u);
    const double ds = u < 1.0 ? -0.5 * kPi * std::sin(kPi * u) / kTaperDeg : 0.0;
    const double env = amp * e[i] / e_max, denv = amp * (w[i] - e[i]) / (params.decay_s * in.deg_per_s) / e_max;
    for (std::size_t k = 0; k < kRingingModes; ++k) {
      const double rate = 2.0 * kPi * draper_frequency_hz(kDraperAlpha[k], c, in.bore_m) / in.deg_per_s;  // rad/deg
      if (i > 0) phase[k] += 0.5 * h * (rate_prev[k] + rate);
      rate_prev[k] = rate;
      const double g = params.mode_weights[k];
      if (g == 0.0 || th < in.soc_deg) continue;
      const double cs = std::cos(phase[k]), sn = std::sin(phase[k]);
      p[i] += g * env * s * cs;
      dp[i] += g * ((denv * s + env * ds) * cs - env * s * rate * sn);
    }
  }
  return amp;
}

}  // namespace noisemon::model::engine
