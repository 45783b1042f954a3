#include "dsp/weighting.hpp"

#include <cmath>
#include <numbers>

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

std::vector<Biquad> a_weighting_sections(double fs_hz) {
  const double t = 1.0 / fs_hz;
  auto bilinear = [&](double f) {  // a real pole at -2 pi f through the bilinear transform
    const double p = -2.0 * std::numbers::pi * f * t / 2.0;
    return (1.0 + p) / (1.0 - p);
  };
  const double p1 = bilinear(kF1), p2 = bilinear(kF2), p3 = bilinear(kF3);
  const double p4 = std::exp(-2.0 * std::numbers::pi * kF4 * t);
  // Sections: zeros (1, 1) with poles (p1, p1); zeros (1, 1) with (p2, p3); poles (p4, p4) without zeros.
  std::vector<Biquad> s{
      {1.0, -2.0, 1.0, -2.0 * p1, p1 * p1}, {1.0, -2.0, 1.0, -(p2 + p3), p2 * p3}, {1.0, 0.0, 0.0, -2.0 * p4, p4 * p4}};
  const double gain = std::abs(cascade_response(s, 1000.0, fs_hz));
  s[2].b0 /= gain;
  return s;
}

}  // namespace noisemon::dsp
