// IIR filter design in second-order sections (bilinear transform with prewarping) and the exact
// frequency response / group delay of a designed cascade. Used by the band filter bank; designs are
// done in double once, at construction.
#pragma once

#include <complex>
#include <vector>

namespace noisemon::dsp {

// y[n] = b0 x[n] + b1 x[n-1] + b2 x[n-2] - a1 y[n-1] - a2 y[n-2]
struct Biquad {
  double b0 = 1, b1 = 0, b2 = 0, a1 = 0, a2 = 0;
};

// Butterworth band-pass from an order-n low-pass prototype: n sections (filter order 2n). The band
// edges f_lo, f_hi are the -3 dB points exactly (prewarped); unit gain at the centre of the band.
std::vector<Biquad> butterworth_bandpass(int n, double f_lo_hz, double f_hi_hz, double fs_hz);

// Butterworth high-pass of even order m (m/2 sections); -3 dB at fc (prewarped), unit gain at fs/2.
std::vector<Biquad> butterworth_highpass(int m, double fc_hz, double fs_hz);

// Chebyshev type II (inverse Chebyshev) low-pass of even order m (m/2 sections): monotonic pass band
// with unit gain at DC, equiripple stop band at least stop_atten_db down from f_stop_hz to fs/2.
std::vector<Biquad> chebyshev2_lowpass(int m, double f_stop_hz, double stop_atten_db, double fs_hz);

// Complex response of the cascade at f_hz.
std::complex<double> cascade_response(const std::vector<Biquad>& sections, double f_hz, double fs_hz);

// Group delay of the cascade at f_hz, in samples.
double cascade_group_delay_samples(const std::vector<Biquad>& sections, double f_hz, double fs_hz);

}  // namespace noisemon::dsp
