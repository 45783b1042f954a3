// The crank-angle resampler's interpolation kernel (dsp/resample.cpp, NonuniformResampler): a Kaiser-windowed sinc
// of 2 W taps tabulated at kKernelPhases fractional offsets, built once per process. Internal to dsp/.
#pragma once

#include <cstddef>
#include <vector>

namespace noisemon::dsp::sinc_kernel {

constexpr std::size_t kKernelHalfWidth = 16;  // taps each side of the interpolation instant
constexpr std::size_t kKernelTaps = 2 * kKernelHalfWidth;
constexpr std::size_t kKernelPhases = 1024;  // kernel table resolution (linear interpolation between rows)
constexpr double kKernelAttenuationDb = 90.0;
// Transition of the windowed sinc is centred on 0.5 cycles/sample with width (A - 8) / (2.285 * 2 pi * 2W);
// the passband ends half a width below (0.41 for W = 16, A = 90 dB; the tests measure it).
constexpr double kIndexPassband =
    0.5 - 0.5 * (kKernelAttenuationDb - 8.0) / (2.285 * 2.0 * 3.141592653589793 * 2.0 * kKernelHalfWidth);

// The table, (kKernelPhases + 1) rows of kKernelTaps: row r, tap k is the windowed sinc at offset
// r / kKernelPhases + W - 1 - k (tap k is sample cursor - W + 1 + k); every row sums to 1.
const std::vector<double>& shared_interpolation_table();

}  // namespace noisemon::dsp::sinc_kernel
