#include "dsp/welch.hpp"

#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace noisemon::dsp {

std::size_t welch(const std::vector<std::vector<double>>& a, const std::vector<std::vector<double>>& b,
                  std::size_t nfft, std::vector<std::complex<double>>& sab, std::vector<double>& saa) {
  Eigen::FFT<double> fft;
  sab.assign(nfft / 2 + 1, 0.0);
  saa.assign(nfft / 2 + 1, 0.0);
  std::vector<double> wa(nfft), wb(nfft), win(nfft);
  for (std::size_t i = 0; i < nfft; ++i)
    win[i] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(nfft));
  std::vector<std::complex<double>> fa, fb;
  std::size_t windows = 0;
  for (std::size_t s = 0; s < a.size(); ++s) {
    const auto& xa = a[s];
    const auto& xb = b[s];
    for (std::size_t start = 0; start + nfft <= xa.size(); start += nfft / 2) {
      double ma = 0.0, mb = 0.0;
      for (std::size_t i = 0; i < nfft; ++i) {
        ma += xa[start + i];
        mb += xb[start + i];
      }
      ma /= static_cast<double>(nfft);
      mb /= static_cast<double>(nfft);
      for (std::size_t i = 0; i < nfft; ++i) {
        wa[i] = (xa[start + i] - ma) * win[i];
        wb[i] = (xb[start + i] - mb) * win[i];
      }
      fft.fwd(fa, wa);
      fft.fwd(fb, wb);
      for (std::size_t k = 0; k <= nfft / 2; ++k) {
        sab[k] += std::conj(fa[k]) * fb[k];
        saa[k] += std::norm(fa[k]);
      }
      ++windows;
    }
  }
  return windows;
}

std::size_t welch_nfft(const std::vector<std::vector<double>>& x) {
  std::size_t longest = 0;
  for (const auto& v : x) longest = std::max(longest, v.size());
  std::size_t n = 64;
  while (n * 2 <= std::min<std::size_t>(longest / 4, 4096)) n *= 2;
  return n;
}

std::vector<BandRms> third_octave_rms(const std::vector<std::vector<double>>& segments, double fs_hz) {
  const std::size_t nfft = welch_nfft(segments);
  std::vector<std::complex<double>> sxx_c;
  std::vector<double> sxx;
  const std::size_t windows = welch(segments, segments, nfft, sxx_c, sxx);
  std::vector<BandRms> out;
  if (windows == 0) return out;
  // Hann window power: sum w^2 = 3 nfft / 8. One-sided mean square per bin: 2 |X|^2 / (sum w^2 nfft).
  const double norm =
      2.0 / (static_cast<double>(windows) * 0.375 * static_cast<double>(nfft) * static_cast<double>(nfft));
  const double df = fs_hz / static_cast<double>(nfft);
  for (int band = -20; band <= 43; ++band) {  // 10 mHz .. 20 kHz
    const double fc = std::pow(10.0, band / 10.0);
    const double lo = fc * std::pow(10.0, -0.05), hi = fc * std::pow(10.0, 0.05);
    if (lo < df || hi > fs_hz / 2.0 * 1.0001) continue;
    double ms = 0.0;
    std::size_t bins = 0;
    for (std::size_t k = 1; k <= nfft / 2; ++k) {
      const double f = df * static_cast<double>(k);
      if (f >= lo && f < hi) {
        ms += sxx[k] * norm;
        ++bins;
      }
    }
    if (bins > 0) out.push_back({fc, lo, hi, std::sqrt(ms)});
  }
  return out;
}

}  // namespace noisemon::dsp
