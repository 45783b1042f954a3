// Where one converter's scans fall on another clock: the time (s, on the reference clock) of scan position q of a
// converter on its own crystal, tracked from observations "scan q was at time t" by a two-state Kalman filter
// (the time at the latest observation, and the scan period). The period wanders slowly (a crystal's temperature),
// a random walk of rate_walk_per_sqrt_s; each observation has its own noise. The filter gives the time of any scan
// and its 1-sigma uncertainty, the clocks' ratio in ppm and an innovation gate that rejects outliers.
#pragma once

#include <cstdint>

namespace noisemon::drivers {

class ClockTracker {
 public:
  struct Options {
    double nominal_rate_hz = 48000.0;
    double initial_sigma_s = 1e-3;       // how well the first origin is known
    double initial_ppm_sigma = 200.0;    // how far the crystal may be off its nominal rate
    double rate_walk_per_sqrt_s = 1e-8;  // relative rate wander (1e-8: 0.01 ppm in a second)
    double gate_sigmas = 5.0;            // an observation this many sigmas off the prediction is rejected
  };

  // Scan 0 at origin_s on the reference clock.
  ClockTracker(const Options& options, double origin_s);

  // Scan position q (in scans, fractional) was at reference time t_s, with 1-sigma noise sigma_s. Positions must not
  // go back (an earlier one is refused). Returns false when refused or rejected by the gate (counted).
  // gate_sigmas > 0 replaces the options' gate for this observation.
  bool observe(double q, double t_s, double sigma_s, double gate_sigmas = 0.0);
  // Starts over from an observation (a re-acquisition): scan q at t_s, keeping the rate and its uncertainty.
  void reset_at(double q, double t_s, double sigma_s);
  // Starts over from a line fitted elsewhere: scan q at t_s, the period and their 1-sigma uncertainties.
  void reset_at(double q, double t_s, double sigma_s, double period_s, double period_sigma_s);

  [[nodiscard]] double time_at(double q) const;                // reference time of scan q
  [[nodiscard]] double sigma_at(double q) const;               // its 1-sigma uncertainty, s
  [[nodiscard]] double period_s() const { return period_s_; }  // seconds per scan on the reference clock
  [[nodiscard]] double ppm() const;  // the converter's rate against its nominal, parts per million
  [[nodiscard]] double ppm_sigma() const;
  [[nodiscard]] double last_position() const { return q_ref_; }
  [[nodiscard]] std::uint64_t accepted() const { return accepted_; }
  [[nodiscard]] std::uint64_t rejected() const { return rejected_; }

 private:
  struct Predicted {
    double t, p00, p01, p11;
  };
  [[nodiscard]] Predicted predict(double q) const;

  Options options_;
  double nominal_period_s_;
  double q_ref_ = 0.0;      // the position of the latest observation
  double t_ref_;            // its time
  double period_s_;         // seconds per scan
  double p00_, p01_, p11_;  // covariance of (t_ref, period)
  std::uint64_t accepted_ = 0, rejected_ = 0;
};

}  // namespace noisemon::drivers
