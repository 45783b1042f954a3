// A microphone front-end on a crystal of its own, written for the clock-alignment tests and benchmark from the
// physics alone (shares no code with drivers/aligned_stream): an engine whose speed wanders, its crank passing a
// sync angle once a revolution at known instants on the encoder's clock, and a card whose scan j is taken at
// t0 + j / (rate * (1 + ppm 1e-6)) plus its own phase jitter. The card samples three tones (the "microphone") and a
// band-limited pulse train (the sync channel: an erf edge of rise_s at each crank instant, pulse_fraction of a
// revolution wide). The host reads a period of scans at a time and sees each reading late by a uniform part of the
// period plus an exponential scheduling delay. Every instant is in seconds on the encoder's clock.
#pragma once

#include <cmath>
#include <cstdint>
#include <deque>
#include <random>
#include <vector>

namespace noisemon::test {

struct DriftingCardSpec {
  double rate_hz = 48000.0;
  double ppm = 80.0;
  double jitter_s = 20e-9;                                            // the card clock's phase jitter, rms
  double t0_s = 0.5;                                                  // scan 0
  double rpm_low = 1500.0, rpm_high = 3000.0, speed_period_s = 37.0;  // the engine's speed wanders between these
  double rise_s = 5e-6;                                               // the sync edge's rise (erf)
  double pulse_fraction = 0.05;                                       // the sync pulse's width, of a revolution
  double sync_noise = 0.002;                                          // the sync channel's noise, rms (full scale 1)
  double tone_hz[3] = {13.0, 997.0, 3163.0};  // the "microphone": the lowest makes a delay of up to 38 ms unambiguous
  double tone_amplitude[3] = {0.3, 0.5, 0.3};
  std::uint32_t period_scans = 480;  // scans per host reading
  double sched_mean_s = 2e-4;        // the host's scheduling delay, mean of an exponential
  std::uint64_t seed = 7;
};

class DriftingCard {
 public:
  explicit DriftingCard(const DriftingCardSpec& spec) : spec_(spec), rng_(spec.seed) { extend_revolutions(1.0); }

  // The engine's crank angle in revolutions at t (the speed's integral).
  double revolutions_at(double t) const {
    const double mean = 0.5 * (spec_.rpm_low + spec_.rpm_high) / 60.0;
    const double swing = 0.5 * (spec_.rpm_high - spec_.rpm_low) / 60.0;
    const double w = 2.0 * M_PI / spec_.speed_period_s;
    return mean * t + swing * (1.0 - std::cos(w * t)) / w;
  }
  // The instant the crank completes revolution n (n >= 1), by bisection of revolutions_at.
  double instant_of_revolution(double n) const {
    double lo = 0.0, hi = 1.0;
    while (revolutions_at(hi) < n) hi *= 2.0;
    for (int i = 0; i < 80; ++i) {
      const double mid = 0.5 * (lo + hi);
      (revolutions_at(mid) < n ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
  }
  // The "microphone": three tones, exact at any instant.
  double mic_at(double t) const {
    double v = 0.0;
    for (int i = 0; i < 3; ++i) v += spec_.tone_amplitude[i] * std::sin(2.0 * M_PI * spec_.tone_hz[i] * t);
    return v;
  }
  const DriftingCardSpec& spec() const { return spec_; }
  double scan_instant(std::uint64_t j) const {
    return spec_.t0_s + static_cast<double>(j) / (spec_.rate_hz * (1.0 + 1e-6 * spec_.ppm));
  }

  // The next scan: its microphone value, its sync value, and its true instant.
  struct Scan {
    double mic, sync, t;
  };
  Scan next() {
    const double t = scan_instant(j_++) + jitter_(rng_) * spec_.jitter_s;
    extend_revolutions(t + 1.0);
    while (edges_.size() > 2 && edges_[1] < t - 0.5) edges_.pop_front();
    double sync = 0.0;
    for (double e : edges_) {
      const double width = spec_.pulse_fraction * revolution_s_;
      sync += 0.5 * (std::erf((t - e) / spec_.rise_s) - std::erf((t - e - width) / spec_.rise_s));
    }
    return {mic_at(t), 0.8 * sync - 0.4 + spec_.sync_noise * jitter_(rng_), t};
  }
  // After every period_scans scans: the host instant the reading was seen at.
  bool reading_due() const { return j_ % spec_.period_scans == 0; }
  double reading_instant() {
    const double captured = scan_instant(j_ - 1);
    return captured + uniform_(rng_) * spec_.period_scans / spec_.rate_hz +
           std::exponential_distribution<double>(1.0 / spec_.sched_mean_s)(rng_);
  }
  std::uint64_t scans() const { return j_; }
  // The crank instants up to t (each once), for the reference the pipeline posts.
  std::vector<double> crank_instants_until(double t) {
    std::vector<double> out;
    while (posted_ < all_edges_.size() && all_edges_[posted_] <= t) out.push_back(all_edges_[posted_++]);
    return out;
  }

 private:
  void extend_revolutions(double until) {
    while (next_rev_t_ <= until) {
      next_rev_t_ = instant_of_revolution(static_cast<double>(next_rev_));
      revolution_s_ = next_rev_ > 1 ? next_rev_t_ - all_edges_.back() : next_rev_t_;
      edges_.push_back(next_rev_t_);
      all_edges_.push_back(next_rev_t_);
      ++next_rev_;
    }
  }

  DriftingCardSpec spec_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> jitter_{0.0, 1.0};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::uint64_t j_ = 0;
  std::int64_t next_rev_ = 1;
  double next_rev_t_ = 0.0, revolution_s_ = 0.04;
  std::deque<double> edges_;
  std::vector<double> all_edges_;
  std::size_t posted_ = 0;
};

}  // namespace noisemon::test
