#include "dsp/weighting.hpp"

#include <cmath>

namespace noisemon::dsp {
namespace {

// IEC 61672-1 annex E: pole frequencies and the normalisation constants that make 1 kHz 0 dB.
constexpr double kF1 = 20.598997;
constexpr double kF2 = 107.65265;
constexpr double kF3 = 737.86223;
constexpr double kF4 = 12194.217;
constexpr double kA1000 = -2.000;
constexpr double kC1000 = -0.062;

}  // namespace

double c_weighting_db(double f_hz) {
  const double f2 = f_hz * f_hz;
  return 20.0 * std::log10(kF4 * kF4 * f2 / ((f2 + kF1 * kF1) * (f2 + kF4 * kF4))) - kC1000;
}

double a_weighting_db(double f_hz) {
  const double f2 = f_hz * f_hz;
  const double num = kF4 * kF4 * f2 * f2;
  const double den = (f2 + kF1 * kF1) * std::sqrt((f2 + kF2 * kF2) * (f2 + kF3 * kF3)) * (f2 + kF4 * kF4);
  return 20.0 * std::log10(num / den) - kA1000;
}

}  // namespace noisemon::dsp
