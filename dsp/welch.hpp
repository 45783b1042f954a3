// Welch spectra of signals cut into segments (Hann window, 50 % overlap, each window's mean removed; windows never
// cross a segment), and the rms per base-10 1/3-octave band from them: engine-free spectral estimation for the
// waveform diagnosis's residuals.
#pragma once

#include <complex>
#include <cstddef>
#include <vector>

namespace noisemon::dsp {

// The cross spectrum conj(A) B and the auto spectrum |A|^2 of a and b on nfft bins (0 .. nfft/2), summed over the
// windows of every segment (unnormalised: callers use ratios or normalise themselves). a and b: the same segments'
// lengths. Returns the number of windows summed.
std::size_t welch(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b,
                  std::size_t nfft, std::vector<std::complex<double>>& sab, std::vector<double>& saa);

// A power of two for Welch on these segments: a quarter of the longest, 64 ... 4096.
std::size_t welch_nfft(const std::vector<std::vector<double>>& segments);

// The Welch power spectrum integrated over base-10 1/3-octave bands (IEC 61260-1 centres) between the frequency
// resolution and fs/2: the rms of the segments per band. Bands with no frequency bin are left out.
struct BandRms {
  double f_center_hz, f_lo_hz, f_hi_hz, rms;
};
std::vector<BandRms> third_octave_rms(const std::vector<std::vector<double>>& segments, double fs_hz);

}  // namespace noisemon::dsp
