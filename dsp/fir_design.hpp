// Kaiser-window FIR design (Kaiser's empirical formulas, Oppenheim & Schafer, Discrete-Time Signal
// Processing, 3rd ed., sec. 7.6): linear-phase windowed-sinc low-pass filters for the resamplers.
// Frequencies are in cycles per sample of the rate the filter runs at (0.5 = Nyquist).
#pragma once

#include <cstddef>
#include <vector>

namespace noisemon::dsp::fir {

// sin(pi x) / (pi x), 1 at x = 0.
double sinc(double x);

// Kaiser window shape parameter for a stopband attenuation (dB); the passband ripple is about the same
// fraction (80 dB -> 1e-4).
double kaiser_beta(double attenuation_db);

// Half length J of a centred filter (2J + 1 taps) that reaches the attenuation over the transition width.
std::size_t kaiser_half_length(double attenuation_db, double transition_width);

// Modified Bessel function of the first kind, order 0.
double bessel_i0(double x);

// Kaiser window at x in [-1, 1] (0 outside), 1 at x = 0.
double kaiser_window(double x, double beta);

// Centred low-pass h[n], n = -J..J stored at [n + J]: 2 fc sinc(2 fc n) times the Kaiser window.
// DC gain is 1 to within the design ripple (callers normalise where they need it exact).
std::vector<double> kaiser_lowpass(std::size_t half_length, double cutoff, double beta);

}  // namespace noisemon::dsp::fir
