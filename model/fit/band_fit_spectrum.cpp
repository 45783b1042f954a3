// The frequency-domain view of a condition the shortcut works on: the measured pressure's power per frequency bin,
// and per band the bins its filter passes with their weights W_b(f) S(f).
#include <unsupported/Eigen/FFT>

#include <cmath>
#include <complex>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit::band_fit_internal {
namespace {

constexpr double kCompressFromHz = 400.0;  // spectrum bins merged into 1/48-octave bins above this
constexpr double kTapFloor = 1e-8;         // band response below which a bin is left out of a band's sum

std::size_t next_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

// A per-band density at each bin: linear in log frequency between the bands' mid frequencies, held beyond them.
std::vector<double> floor_per_bin(const BandDataset& data, const std::vector<double>& per_band,
                                  const std::vector<double>& f_hz) {
  if (per_band.empty()) return {};
  std::vector<double> out(f_hz.size());
  const std::size_t nb = std::min(per_band.size(), data.band_count());
  std::size_t b = 0;
  for (std::size_t j = 0; j < f_hz.size(); ++j) {
    const double f = f_hz[j];
    while (b + 1 < nb && data.bands[b + 1].exact_mid_hz <= f) ++b;
    const double lo = data.bands[b].exact_mid_hz;
    if (f <= lo || b + 1 >= nb) {
      out[j] = per_band[b];
      continue;
    }
    const double t = std::log(f / lo) / std::log(data.bands[b + 1].exact_mid_hz / lo);
    out[j] = (1.0 - t) * per_band[b] + t * per_band[b + 1];
  }
  return out;
}

// Hann-windowed spectrum of the pressure over [from, to) of the segment (mean removed), zero-padded to nfft.
std::vector<std::complex<double>> pressure_fft(const PreparedSegment& seg, std::size_t from, std::size_t to,
                                               std::size_t nfft, double& wsum2) {
  const std::size_t n = to - from;
  std::vector<double> buf(nfft, 0.0);
  double mean = 0.0;
  for (std::size_t i = from; i < to; ++i) mean += seg.pressure_pa[i];
  mean /= static_cast<double>(n);
  wsum2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = 0.5 - 0.5 * std::cos(2.0 * kPi * (static_cast<double>(i) + 0.5) / static_cast<double>(n));
    buf[i] = (seg.pressure_pa[from + i] - mean) * w;
    wsum2 += w * w;
  }
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> X;
  fft.fwd(X, buf);
  return X;
}

// One-sided power per FFT bin (Pa^2), merged into 1/48-octave bins above kCompressFromHz, into sp's bins.
void power_bins(const std::vector<std::complex<double>>& X, std::size_t nfft, double wsum2, ConditionSpectrum& sp) {
  const double df = kDatasetRateHz / static_cast<double>(nfft);
  double acc_p = 0.0, acc_pf = 0.0, acc_df = 0.0, edge = kCompressFromHz;
  auto flush = [&]() {
    if (acc_df <= 0.0) return;
    if (acc_p > 0.0) {
      sp.f_hz.push_back(acc_pf / acc_p);
      sp.df_hz.push_back(acc_df);
      sp.s.push_back(acc_p);
    }
    acc_p = acc_pf = acc_df = 0.0;
  };
  for (std::size_t j = 1; j < nfft / 2; ++j) {
    const double f = static_cast<double>(j) * df;
    // Parseval over the zero-padded transform: the one-sided bins sum to the windowed mean square of the n
    // samples, whatever nfft is.
    const double p = 2.0 * std::norm(X[j]) / (static_cast<double>(nfft) * wsum2);
    if (f < kCompressFromHz) {
      if (p > 0.0) {
        sp.f_hz.push_back(f);
        sp.df_hz.push_back(df);
        sp.s.push_back(p);
      }
      continue;
    }
    while (f >= edge * std::pow(2.0, 1.0 / 48.0)) {
      flush();
      edge *= std::pow(2.0, 1.0 / 48.0);
    }
    acc_p += p;
    acc_pf += p * f;
    acc_df += df;
  }
  flush();
}

}  // namespace

double band_power_response(const dsp::ThirdOctaveBand& band, double f) {
  if (f <= 0.0) return 0.0;
  if (band.nyquist_cut) return 1.0 / (1.0 + std::pow(band.lower_edge_hz / f, 16));
  const double f0sq = band.lower_edge_hz * band.upper_edge_hz;
  const double x = (f * f - f0sq) / (f * (band.upper_edge_hz - band.lower_edge_hz));
  return 1.0 / (1.0 + std::pow(x * x, 4));
}

ConditionSpectrum condition_spectrum(const BandDataset& data, std::size_t k, std::size_t cycles) {
  const ConditionData& cond = data.conditions[k];
  const PreparedSegment& seg = cond.segments.front();
  const std::size_t from = seg.data_start, to = segment_frames(seg, cycles);
  const std::size_t n = to - from;
  const std::size_t nfft = next_pow2(n);
  double wsum2 = 0.0;
  const std::vector<std::complex<double>> X = pressure_fft(seg, from, to, nfft, wsum2);
  ConditionSpectrum sp;
  power_bins(X, nfft, wsum2, sp);
  sp.floor = floor_per_bin(data, cond.info.floor_density, sp.f_hz);
  sp.band_taps.resize(data.band_count());
  for (std::size_t b = 0; b < data.band_count(); ++b)
    for (std::size_t j = 0; j < sp.f_hz.size(); ++j) {
      const double w = band_power_response(data.bands[b], sp.f_hz[j]);
      if (w > kTapFloor) sp.band_taps[b].push_back({j, w * sp.s[j]});
    }
  return sp;
}

}  // namespace noisemon::model::fit::band_fit_internal
