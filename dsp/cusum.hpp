// Page's two-sided CUSUM on standardised observations (zero mean, unit variance while nothing changes), its
// threshold set from a target average run length between false alarms, not guessed.
//
//   S+ = max(0, S+ + z - k),  S- = max(0, S- - z - k),  alarm when either exceeds h.
//
// k is half the smallest shift to detect (in standard deviations): the test is then optimal for that shift.
// The average run length to a false alarm of one side, ARL0(k, h), and to detection of a shift mu, follow
// Siegmund's approximation (Siegmund 1985, Sequential Analysis, eq. 2.55; Montgomery, Introduction to Statistical
// Quality Control, 6th ed., sec. 9.1.6): with b = h + 1.166 and D = mu - k,
//   ARL(mu) = (exp(-2 D b) + 2 D b - 1) / (2 D^2),   ARL(mu) = b^2 when D = 0.
// The onset is the observation after the last time the firing side stood at zero (the maximum-likelihood change
// point of the CUSUM).
#pragma once

#include <cstdint>

namespace noisemon::dsp {

// Siegmund's ARL of one side of the CUSUM (k, h) when the mean is `shift` standard deviations (0: in control).
[[nodiscard]] double cusum_arl(double k, double h, double shift = 0.0);
// The threshold h >= 0 whose in-control ARL of one side is `arl0` observations (bisection on cusum_arl).
[[nodiscard]] double cusum_threshold(double k, double arl0);

class Cusum {
 public:
  Cusum() = default;
  Cusum(double k, double h) : k_(k), h_(h) {}

  // One standardised observation with its index; +1 or -1 when the upper or lower side crosses h (then both sides
  // restart from zero), 0 otherwise.
  [[nodiscard]] int update(double z, std::int64_t index);
  // After an alarm: the index of the first observation of the change (the one after the firing side's last zero).
  [[nodiscard]] std::int64_t onset() const { return onset_; }
  void reset();
  double k() const { return k_; }
  double h() const { return h_; }
  double upper() const { return upper_; }
  double lower() const { return lower_; }

 private:
  double k_ = 0.5, h_ = 5.0;
  double upper_ = 0.0, lower_ = 0.0;
  std::int64_t upper_start_ = 0, lower_start_ = 0;  // index after each side's last zero
  std::int64_t onset_ = 0;
};

}  // namespace noisemon::dsp
