#include "dsp/cusum.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace noisemon::dsp {

double cusum_arl(double k, double h, double shift) {
  const double b = h + 1.166;
  const double d = shift - k;
  if (std::abs(d) < 1e-9) return b * b;
  return (std::exp(-2.0 * d * b) + 2.0 * d * b - 1.0) / (2.0 * d * d);
}

double cusum_threshold(double k, double arl0) {
  if (!(k > 0.0) || !(arl0 > 1.0)) throw std::invalid_argument("cusum_threshold: k must be positive and arl0 above 1");
  if (cusum_arl(k, 0.0) >= arl0) return 0.0;
  double lo = 0.0, hi = 1.0;
  while (cusum_arl(k, hi) < arl0) hi *= 2.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (cusum_arl(k, mid) < arl0 ? lo : hi) = mid;
  }
  return hi;
}

int Cusum::update(double z, std::int64_t index) {
  if (upper_ == 0.0) upper_start_ = index;
  if (lower_ == 0.0) lower_start_ = index;
  upper_ = std::max(0.0, upper_ + z - k_);
  lower_ = std::max(0.0, lower_ - z - k_);
  int side = 0;
  if (upper_ > h_) {
    side = 1;
    onset_ = upper_start_;
  } else if (lower_ > h_) {
    side = -1;
    onset_ = lower_start_;
  }
  if (side != 0) reset();
  return side;
}

void Cusum::reset() {
  upper_ = 0.0;
  lower_ = 0.0;
}

}  // namespace noisemon::dsp
