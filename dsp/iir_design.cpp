#include "dsp/iir_design.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace noisemon::dsp {
namespace {

using cd = std::complex<double>;

// Analog frequencies are expressed as tan(pi f / fs), so the bilinear map is z = (1 + s) / (1 - s).
double prewarp(double f_hz, double fs_hz) { return std::tan(kPi * f_hz / fs_hz); }
cd bilinear(cd s) { return (1.0 + s) / (1.0 - s); }

// Denominator 1 - 2 Re(p) z^-1 + |p|^2 z^-2 of a conjugate pole pair p, p*.
void set_poles(Biquad& q, cd pole_z) {
  q.a1 = -2.0 * pole_z.real();
  q.a2 = std::norm(pole_z);
}

void scale_to_unit_gain(Biquad& q, double f_hz, double fs_hz) {
  const double g = 1.0 / std::abs(cascade_response({q}, f_hz, fs_hz));
  q.b0 *= g;
  q.b1 *= g;
  q.b2 *= g;
}

// Left-half-plane poles of the order-n Butterworth low-pass prototype (cutoff 1 rad/s).
std::vector<cd> butterworth_prototype(int n) {
  std::vector<cd> p;
  for (int k = 0; k < n; ++k) p.push_back(std::polar(1.0, kPi * (2.0 * k + n + 1) / (2.0 * n)));
  return p;
}

std::vector<cd> upper_half(const std::vector<cd>& poles) {
  std::vector<cd> out;
  for (cd p : poles)
    if (p.imag() > 0) out.push_back(p);
  return out;
}

}  // namespace

std::vector<Biquad> butterworth_bandpass(int n, double f_lo_hz, double f_hi_hz, double fs_hz) {
  if (n < 1 || !(0 < f_lo_hz && f_lo_hz < f_hi_hz && f_hi_hz < fs_hz / 2))
    throw std::invalid_argument("butterworth_bandpass: need 0 < f_lo < f_hi < fs/2");
  const double wl = prewarp(f_lo_hz, fs_hz), wu = prewarp(f_hi_hz, fs_hz);
  const double w0 = std::sqrt(wl * wu), bw = wu - wl;
  // Low-pass to band-pass: s_lp = (s^2 + w0^2) / (bw s); each prototype pole gives two band-pass poles.
  std::vector<cd> poles;
  for (cd p : butterworth_prototype(n)) {
    const cd root = std::sqrt(p * p * bw * bw - 4.0 * w0 * w0);
    poles.push_back((p * bw + root) / 2.0);
    poles.push_back((p * bw - root) / 2.0);
  }
  poles = upper_half(poles);
  // An odd prototype's real pole gives two real band-pass poles once bw >= 2 w0: not pairable here.
  if (poles.size() != static_cast<std::size_t>(n)) throw std::invalid_argument("butterworth_bandpass: band too wide");
  const double f_centre = std::atan(w0) * fs_hz / kPi;
  std::vector<Biquad> out;
  for (cd s : poles) {
    Biquad q{1.0, 0.0, -1.0, 0, 0};  // one zero at s = 0 (z = 1), one at infinity (z = -1)
    set_poles(q, bilinear(s));
    scale_to_unit_gain(q, f_centre, fs_hz);
    out.push_back(q);
  }
  return out;
}

std::vector<Biquad> butterworth_highpass(int m, double fc_hz, double fs_hz) {
  if (m < 2 || m % 2 != 0 || !(0 < fc_hz && fc_hz < fs_hz / 2))
    throw std::invalid_argument("butterworth_highpass: need even order and 0 < fc < fs/2");
  const double wc = prewarp(fc_hz, fs_hz);
  std::vector<cd> poles;
  for (cd p : butterworth_prototype(m)) poles.push_back(wc / p);
  std::vector<Biquad> out;
  for (cd s : upper_half(poles)) {
    Biquad q{1.0, -2.0, 1.0, 0, 0};  // double zero at s = 0 (z = 1)
    set_poles(q, bilinear(s));
    scale_to_unit_gain(q, fs_hz / 2, fs_hz);
    out.push_back(q);
  }
  return out;
}

std::vector<Biquad> chebyshev2_lowpass(int m, double f_stop_hz, double stop_atten_db, double fs_hz) {
  if (m < 2 || m % 2 != 0 || !(0 < f_stop_hz && f_stop_hz < fs_hz / 2) || stop_atten_db <= 0)
    throw std::invalid_argument("chebyshev2_lowpass: need even order, 0 < f_stop < fs/2, attenuation > 0");
  const double ws = prewarp(f_stop_hz, fs_hz);
  const double eps = 1.0 / std::sqrt(std::pow(10.0, stop_atten_db / 10.0) - 1.0);
  const double mu = std::asinh(1.0 / eps) / m;
  // Poles: reciprocals of the Chebyshev type I poles (scaled to the stop edge); zeros on the j axis.
  std::vector<cd> poles, zeros;
  for (int k = 1; k <= m; ++k) {
    const double th = kPi * (2.0 * k - 1) / (2.0 * m);
    const cd p1(-std::sinh(mu) * std::sin(th), std::cosh(mu) * std::cos(th));
    poles.push_back(ws / p1);
    if (std::cos(th) > 0) zeros.push_back(cd(0, ws / std::cos(th)));
  }
  poles = upper_half(poles);
  // Pair each pole with the nearest unused zero, highest-Q (closest to the j axis) first.
  std::sort(poles.begin(), poles.end(), [](cd a, cd b) { return -a.real() / std::abs(a) < -b.real() / std::abs(b); });
  std::vector<Biquad> out;
  for (cd s : poles) {
    auto nearest =
        std::min_element(zeros.begin(), zeros.end(), [&](cd a, cd b) { return std::abs(a - s) < std::abs(b - s); });
    const cd zz = bilinear(*nearest);
    zeros.erase(nearest);
    Biquad q{1.0, -2.0 * zz.real(), std::norm(zz), 0, 0};
    set_poles(q, bilinear(s));
    scale_to_unit_gain(q, 0.0, fs_hz);
    out.push_back(q);
  }
  std::reverse(out.begin(), out.end());  // low Q first
  return out;
}

std::complex<double> cascade_response(const std::vector<Biquad>& sections, double f_hz, double fs_hz) {
  const cd z1 = std::polar(1.0, -2.0 * kPi * f_hz / fs_hz);  // z^-1 on the unit circle
  const cd z2 = z1 * z1;
  cd h = 1.0;
  for (const Biquad& q : sections) h *= (q.b0 + q.b1 * z1 + q.b2 * z2) / (1.0 + q.a1 * z1 + q.a2 * z2);
  return h;
}

double cascade_group_delay_samples(const std::vector<Biquad>& sections, double f_hz, double fs_hz) {
  // Group delay of a polynomial sum c_k z^-k on the unit circle: Re(sum k c_k z^-k / sum c_k z^-k).
  const cd z1 = std::polar(1.0, -2.0 * kPi * f_hz / fs_hz);
  const cd z2 = z1 * z1;
  auto delay = [&](double c0, double c1, double c2) {
    return ((c1 * z1 + 2.0 * c2 * z2) / (c0 + c1 * z1 + c2 * z2)).real();
  };
  double d = 0;
  for (const Biquad& q : sections) d += delay(q.b0, q.b1, q.b2) - delay(1.0, q.a1, q.a2);
  return d;
}

}  // namespace noisemon::dsp
