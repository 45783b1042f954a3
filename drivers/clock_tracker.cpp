#include "drivers/clock_tracker.hpp"

#include <cmath>
#include <stdexcept>

namespace noisemon::drivers {

ClockTracker::ClockTracker(const Options& options, double origin_s)
    : options_(options), nominal_period_s_(1.0 / options.nominal_rate_hz), t_ref_(origin_s) {
  if (!(options.nominal_rate_hz > 0.0) || !(options.initial_sigma_s > 0.0) || !(options.initial_ppm_sigma > 0.0) ||
      !(options.rate_walk_per_sqrt_s >= 0.0) || !(options.gate_sigmas > 0.0))
    throw std::invalid_argument("ClockTracker: rates, sigmas and the gate must be positive");
  period_s_ = nominal_period_s_;
  p00_ = options.initial_sigma_s * options.initial_sigma_s;
  p01_ = 0.0;
  const double period_sigma = options.initial_ppm_sigma * 1e-6 * nominal_period_s_;
  p11_ = period_sigma * period_sigma;
}

// The state carried from the latest observation to q: F = [[1, d], [0, 1]] and the rate's random walk over the d
// scans (white noise on the period: q_c [[d^3/3, d^2/2], [d^2/2, d]] per scan).
ClockTracker::Predicted ClockTracker::predict(double q) const {
  const double d = q - q_ref_;
  const double walk = options_.rate_walk_per_sqrt_s * nominal_period_s_;
  const double qc = walk * walk * nominal_period_s_;  // per scan
  const double ad = std::abs(d);
  Predicted p{};
  p.t = t_ref_ + period_s_ * d;
  p.p00 = p00_ + 2.0 * d * p01_ + d * d * p11_ + qc * ad * ad * ad / 3.0;
  p.p01 = p01_ + d * p11_ + qc * d * ad / 2.0;
  p.p11 = p11_ + qc * ad;
  return p;
}

bool ClockTracker::observe(double q, double t_s, double sigma_s, double gate_sigmas) {
  if (!(q >= q_ref_) || !std::isfinite(t_s) || !(sigma_s > 0.0)) {
    ++rejected_;
    return false;
  }
  const Predicted p = predict(q);
  const double r = sigma_s * sigma_s;
  const double s = p.p00 + r;
  const double innovation = t_s - p.t;
  const double gate = gate_sigmas > 0.0 ? gate_sigmas : options_.gate_sigmas;
  if (innovation * innovation > gate * gate * s) {
    ++rejected_;
    return false;
  }
  const double k0 = p.p00 / s, k1 = p.p01 / s;
  q_ref_ = q;
  t_ref_ = p.t + k0 * innovation;
  period_s_ += k1 * innovation;
  // Joseph form, (I - K H) P (I - K H)' + K R K', which stays positive definite in rounding.
  const double a = 1.0 - k0;
  p00_ = a * a * p.p00 + k0 * k0 * r;
  p01_ = a * (p.p01 - k1 * p.p00) + k0 * k1 * r;
  p11_ = p.p11 - 2.0 * k1 * p.p01 + k1 * k1 * p.p00 + k1 * k1 * r;
  ++accepted_;
  return true;
}

void ClockTracker::reset_at(double q, double t_s, double sigma_s) {
  q_ref_ = q;
  t_ref_ = t_s;
  p00_ = sigma_s * sigma_s;
  p01_ = 0.0;
}

void ClockTracker::reset_at(double q, double t_s, double sigma_s, double period_s, double period_sigma_s) {
  reset_at(q, t_s, sigma_s);
  period_s_ = period_s;
  p11_ = period_sigma_s * period_sigma_s;
}

double ClockTracker::time_at(double q) const { return t_ref_ + period_s_ * (q - q_ref_); }

double ClockTracker::sigma_at(double q) const { return std::sqrt(predict(q).p00); }

double ClockTracker::ppm() const { return (nominal_period_s_ / period_s_ - 1.0) * 1e6; }

double ClockTracker::ppm_sigma() const { return std::sqrt(p11_) / period_s_ * 1e6; }

}  // namespace noisemon::drivers
