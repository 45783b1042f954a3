#include "model/fit/band_dataset.hpp"
#include "model/fit/pressure_floor.hpp"

#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <complex>
#include <numeric>
#include <stdexcept>

namespace noisemon::model::fit {
namespace {

// Complete cycles of one recording: [starts[k], starts[k + 1]) for k < starts.size() - 1, every one with its
// microphone frames inside the recording.
std::vector<std::size_t> complete_cycle_starts(const ConditionRecording& r) {
  std::vector<std::size_t> wraps;
  const std::size_t n = r.pressure_pa.size();
  for (std::size_t i = 1; i < n; ++i)
    if (r.crank_deg[i] < r.crank_deg[i - 1] - 360.0) wraps.push_back(i);
  const std::int64_t mic_frames = r.mic_count > 0 ? static_cast<std::int64_t>(r.mics_pa.size() / r.mic_count) : 0;
  std::vector<std::size_t> out;
  for (std::size_t k = 0; k + 1 < wraps.size(); ++k) {
    const std::int64_t s = static_cast<std::int64_t>(wraps[k]) + r.delay_frames;
    const std::int64_t e = static_cast<std::int64_t>(wraps[k + 1]) + r.delay_frames;
    if (s < 0 || e > mic_frames) {
      if (!out.empty()) break;  // cycles must stay contiguous
      continue;
    }
    if (out.empty()) out.push_back(wraps[k]);
    out.push_back(wraps[k + 1]);
  }
  return out;
}

std::size_t next_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

// A background measurement (engine off) has no crank signal: cut it into blocks of a cycle at 3000 rpm.
ConditionRecording with_block_crank(const ConditionRecording& given) {
  ConditionRecording synthetic = given;
  constexpr std::size_t kBlock = 1600;
  for (std::size_t i = 0; i < synthetic.crank_deg.size(); ++i)
    synthetic.crank_deg[i] = -360.0 + 720.0 * static_cast<double>(i % kBlock) / static_cast<double>(kBlock);
  return synthetic;
}

// Each cycle's pressure and microphone frames (for the coherence estimate).
struct CycleFrames {
  std::vector<std::vector<double>> u, y;
};

// The segment of one recording's complete cycles [starts.front(), starts.back()): the first cycle repeated
// `preroll` times in front, cycle and crank-window starts; and in sig the bank's input, per frame the pressure and
// the microphones with their constant offsets (mean of the first cycle) removed: the bank's slow bands would ring on
// the step otherwise.
PreparedSegment prepare_segment(const ConditionRecording& r, const std::vector<std::size_t>& starts,
                                std::size_t preroll, std::size_t first_cycle, std::vector<double>& sig) {
  const std::size_t M = r.mic_count, ch = 1 + M;
  const std::size_t s0 = starts.front(), e0 = starts[1], len0 = e0 - s0, s_end = starts.back();
  PreparedSegment seg;
  seg.first_cycle = first_cycle;
  seg.data_start = preroll * len0;
  const std::size_t frames = seg.data_start + (s_end - s0);
  seg.pressure_pa.resize(frames);
  sig.assign(frames * ch, 0.0);
  double pmean = 0.0;
  std::vector<double> mmean(M, 0.0);
  for (std::size_t i = s0; i < e0; ++i) {
    pmean += r.pressure_pa[i];
    for (std::size_t m = 0; m < M; ++m) mmean[m] += r.mics_pa[(i + r.delay_frames) * M + m];
  }
  pmean /= static_cast<double>(len0);
  for (double& v : mmean) v /= static_cast<double>(len0);
  for (std::size_t j = 0; j < frames; ++j) {
    const std::size_t i = j < seg.data_start ? s0 + j % len0 : s0 + (j - seg.data_start);
    seg.pressure_pa[j] = r.pressure_pa[i];
    double* f = &sig[j * ch];
    f[0] = r.pressure_pa[i] - pmean;
    const double* mic = &r.mics_pa[(i + r.delay_frames) * M];
    for (std::size_t m = 0; m < M; ++m) f[1 + m] = mic[m] - mmean[m];
  }
  for (std::size_t k = 0; k < starts.size(); ++k) seg.cycle_starts.push_back(seg.data_start + starts[k] - s0);
  for (std::size_t k = 0; k + 1 < starts.size(); ++k) {
    const std::size_t a = starts[k], b = starts[k + 1];
    seg.window_starts.push_back(seg.data_start + a - s0);
    std::size_t i = a;
    for (std::size_t w = 1; w < kW; ++w) {
      const double edge = -360.0 + 720.0 * static_cast<double>(w) / static_cast<double>(kW);
      while (i < b && r.crank_deg[i] < edge) ++i;
      seg.window_starts.push_back(seg.data_start + i - s0);
    }
    seg.window_starts.push_back(seg.data_start + b - s0);
  }
  return seg;
}

// The cycles' durations and speeds, and (with coherence) their frames.
void add_cycles(const ConditionRecording& r, const std::vector<std::size_t>& starts, bool coherence, ConditionData& d,
                CycleFrames& frames) {
  const std::size_t M = r.mic_count;
  for (std::size_t k = 0; k + 1 < starts.size(); ++k) {
    const std::size_t a = starts[k], b = starts[k + 1];
    CycleInfo ci;
    ci.duration_s = static_cast<double>(b - a) / kDatasetRateHz;
    ci.speed_rpm = 120.0 / ci.duration_s;
    d.cycles.push_back(ci);
    if (coherence) {
      frames.u.emplace_back(r.pressure_pa.begin() + static_cast<std::ptrdiff_t>(a),
                            r.pressure_pa.begin() + static_cast<std::ptrdiff_t>(b));
      frames.y.emplace_back(r.mics_pa.begin() + static_cast<std::ptrdiff_t>((a + r.delay_frames) * M),
                            r.mics_pa.begin() + static_cast<std::ptrdiff_t>((b + r.delay_frames) * M));
    }
  }
}

// The segment's band mean squares per cycle (pressure, each microphone) and per crank window (pressure, microphone
// average), appended to the condition's.
void add_band_powers(const PreparedSegment& seg, const std::vector<double>& sig, ConditionData& d) {
  const std::size_t nb = d.bands, M = d.mics, ch = 1 + M;
  std::vector<double> cyc, win;
  segment_band_powers(seg, sig.data(), ch, 0, cyc, &win);
  const std::size_t nc = segment_cycles(seg);
  for (std::size_t c = 0; c < nc; ++c) {
    const double* row = &cyc[c * ch * nb];
    d.cpl_ms.insert(d.cpl_ms.end(), row, row + nb);
    d.mic_ms.insert(d.mic_ms.end(), row + nb, row + ch * nb);
    for (std::size_t w = 0; w < kW; ++w) {
      const double* wr = &win[(c * kW + w) * ch * nb];
      d.cpl_win_ms.insert(d.cpl_win_ms.end(), wr, wr + nb);
      for (std::size_t b = 0; b < nb; ++b) {
        double s = 0.0;
        for (std::size_t m = 0; m < M; ++m) s += wr[(1 + m) * nb + b];
        d.win_ms.push_back(s / static_cast<double>(M));
      }
      d.win_frames.push_back(
          static_cast<double>(seg.window_starts[(c) * (kW + 1) + w + 1] - seg.window_starts[c * (kW + 1) + w]));
    }
  }
}

using Spectra = std::vector<std::vector<std::complex<double>>>;

// Spectra (bins 0 .. nfft / 2) of every cycle's pressure (u) and microphones (y[c * M + m]), each trimmed to the
// shortest cycle (len frames), mean removed, zero-padded to nfft.
void cycle_spectra(const CycleFrames& frames, std::size_t M, std::size_t len, std::size_t nfft, Spectra& U,
                   Spectra& Y) {
  const std::size_t N = frames.u.size();
  Eigen::FFT<double> fft;
  const std::size_t nbins = nfft / 2 + 1;
  U.assign(N, {});
  Y.assign(N * M, {});
  std::vector<double> buf(nfft);
  std::vector<std::complex<double>> spec;
  auto transform = [&](auto get, std::vector<std::complex<double>>& out) {
    double mean = 0.0;
    for (std::size_t i = 0; i < len; ++i) mean += get(i);
    mean /= static_cast<double>(len);
    std::fill(buf.begin(), buf.end(), 0.0);
    for (std::size_t i = 0; i < len; ++i) buf[i] = get(i) - mean;
    fft.fwd(spec, buf);
    out.assign(spec.begin(), spec.begin() + static_cast<std::ptrdiff_t>(nbins));
  };
  for (std::size_t c = 0; c < N; ++c) {
    transform([&](std::size_t i) { return frames.u[c][i]; }, U[c]);
    for (std::size_t m = 0; m < M; ++m) transform([&](std::size_t i) { return frames.y[c][i * M + m]; }, Y[c * M + m]);
  }
}

// Per band sums over its bins and microphones: the periodic (cycle-synchronous average) power, the total power,
// the fluctuations' power and their part coherent with the pressure's fluctuations.
struct CoherenceSums {
  std::vector<double> per, tot, fvar, fcoh;
};

void add_bin(const Spectra& U, const Spectra& Y, std::size_t M, std::size_t k, std::size_t b, CoherenceSums& sums) {
  const std::size_t N = U.size();
  const double Nd = static_cast<double>(N);
  std::complex<double> ubar = 0.0;
  for (std::size_t c = 0; c < N; ++c) ubar += U[c][k];
  ubar /= Nd;
  double var_u = 0.0;
  for (std::size_t c = 0; c < N; ++c) var_u += std::norm(U[c][k] - ubar);
  var_u /= Nd;
  for (std::size_t m = 0; m < M; ++m) {
    std::complex<double> ybar = 0.0;
    for (std::size_t c = 0; c < N; ++c) ybar += Y[c * M + m][k];
    ybar /= Nd;
    double total = 0.0, var_y = 0.0;
    std::complex<double> cross = 0.0;
    for (std::size_t c = 0; c < N; ++c) {
      const std::complex<double>& y = Y[c * M + m][k];
      total += std::norm(y);
      var_y += std::norm(y - ybar);
      cross += (U[c][k] - ubar) * std::conj(y - ybar);
    }
    total /= Nd;
    var_y /= Nd;
    cross /= Nd;
    double g2 = (var_u > 0 && var_y > 0) ? std::norm(cross) / (var_u * var_y) : 0.0;
    g2 = std::max(0.0, (Nd * g2 - 1.0) / (Nd - 1.0));  // remove the 1/N bias of an N-segment estimate
    sums.per[b] += std::norm(ybar);
    sums.tot[b] += total;
    sums.fvar[b] += var_y;
    sums.fcoh[b] += g2 * var_y;
  }
}

// Coherence across cycles (see the header), with at least 4 cycles.
void cycle_coherence(const CycleFrames& frames, const std::vector<dsp::ThirdOctaveBand>& bands, ConditionData& d) {
  const std::size_t nb = d.bands, M = d.mics;
  std::size_t len = frames.u.front().size();
  for (const auto& u : frames.u) len = std::min(len, u.size());
  const std::size_t nfft = next_pow2(len);
  const std::size_t nbins = nfft / 2 + 1;
  Spectra U, Y;
  cycle_spectra(frames, M, len, nfft, U, Y);
  CoherenceSums sums{std::vector<double>(nb, 0.0), std::vector<double>(nb, 0.0), std::vector<double>(nb, 0.0),
                     std::vector<double>(nb, 0.0)};
  for (std::size_t k = 1; k < nbins; ++k) {
    const double f = static_cast<double>(k) * kDatasetRateHz / static_cast<double>(nfft);
    std::size_t b = nb;
    for (std::size_t j = 0; j < nb; ++j)
      if (f >= bands[j].lower_edge_hz && f < bands[j].upper_edge_hz) b = j;
    if (b == nb) continue;
    add_bin(U, Y, M, k, b, sums);
  }
  for (std::size_t b = 0; b < nb; ++b) {
    if (sums.tot[b] <= 0.0) continue;
    d.periodic_share[b] = sums.per[b] / sums.tot[b];
    d.fluct_coherence[b] = sums.fvar[b] > 0 ? sums.fcoh[b] / sums.fvar[b] : 0.0;
    d.coherent_fraction[b] = (sums.per[b] + sums.fcoh[b]) / sums.tot[b];
  }
}

}  // namespace

double ConditionData::mic_avg_ms(std::size_t c, std::size_t b) const {
  double s = 0.0;
  for (std::size_t m = 0; m < mics; ++m) s += mic_ms[(c * mics + m) * bands + b];
  return s / static_cast<double>(mics);
}

double ConditionData::mean_speed_rpm() const {
  double s = 0.0;
  for (const CycleInfo& c : cycles) s += c.speed_rpm;
  return cycles.empty() ? info.speed_rpm : s / static_cast<double>(cycles.size());
}

std::size_t segment_cycles(const PreparedSegment& segment) { return segment.cycle_starts.size() - 1; }

std::size_t segment_frames(const PreparedSegment& segment, std::size_t cycles) {
  const std::size_t n = segment_cycles(segment);
  if (cycles == 0 || cycles > n) cycles = n;
  return segment.cycle_starts[cycles];
}

void segment_band_powers(const PreparedSegment& segment, const double* signal, std::size_t channels, std::size_t cycles,
                         std::vector<double>& cycle_out, std::vector<double>* win_out) {
  const std::size_t n_cycles = (cycles == 0 || cycles > segment_cycles(segment)) ? segment_cycles(segment) : cycles;
  dsp::ThirdOctaveBank bank(kDatasetRateHz, channels);
  const std::size_t nb = bank.band_count();
  const std::size_t row = channels * nb;
  std::vector<double> scratch(row);
  cycle_out.assign(n_cycles * row, 0.0);
  std::unique_ptr<dsp::ThirdOctaveBank> wbank;
  if (win_out) {
    wbank = std::make_unique<dsp::ThirdOctaveBank>(kDatasetRateHz, channels);
    win_out->assign(n_cycles * kW * row, 0.0);
  }
  auto run = [&](std::size_t from, std::size_t to) {
    if (to <= from) return;
    bank.process(signal + from * channels, to - from);
    if (wbank) wbank->process(signal + from * channels, to - from);
  };
  run(0, segment.data_start);
  bank.take_mean_square(scratch.data());
  if (wbank) wbank->take_mean_square(scratch.data());
  for (std::size_t c = 0; c < n_cycles; ++c) {
    if (wbank) {
      for (std::size_t w = 0; w < kW; ++w) {
        const std::size_t a = segment.window_starts[c * (kW + 1) + w], b = segment.window_starts[c * (kW + 1) + w + 1];
        run(a, b);
        wbank->take_mean_square(&(*win_out)[(c * kW + w) * row]);
      }
    } else {
      run(segment.cycle_starts[c], segment.cycle_starts[c + 1]);
    }
    bank.take_mean_square(&cycle_out[c * row]);
  }
}

ConditionData build_condition(const ConditionInfo& info, const std::vector<ConditionRecording>& recordings,
                              const DatasetOptions& options) {
  ConditionData d;
  d.info = info;
  if (recordings.empty()) throw std::invalid_argument("condition " + info.name + ": no recording");
  d.mics = recordings.front().mic_count;
  if (d.mics == 0) throw std::invalid_argument("condition " + info.name + ": the recording has no microphones");
  const dsp::ThirdOctaveBank probe(kDatasetRateHz, 1);
  d.bands = probe.band_count();
  const std::size_t M = d.mics;
  CycleFrames coherence_frames;
  for (const ConditionRecording& given : recordings) {
    const ConditionRecording synthetic = info.background ? with_block_crank(given) : ConditionRecording{};
    const ConditionRecording& r = info.background ? synthetic : given;
    if (r.mic_count != M)
      throw std::invalid_argument("condition " + info.name + ": recordings with " + std::to_string(r.mic_count) +
                                  " and " + std::to_string(M) + " microphones");
    if (r.crank_deg.size() != r.pressure_pa.size() || r.mics_pa.size() % M != 0)
      throw std::invalid_argument("condition " + info.name + ": inconsistent recording sizes");
    std::vector<std::size_t> starts = complete_cycle_starts(r);
    if (starts.size() < 2) continue;
    if (options.max_cycles > 0) {
      const std::size_t left = options.max_cycles > d.cycles.size() ? options.max_cycles - d.cycles.size() : 0;
      if (left == 0) break;
      if (starts.size() - 1 > left) starts.resize(left + 1);
    }
    std::vector<double> sig;
    PreparedSegment seg = prepare_segment(r, starts, options.preroll_cycles, d.cycles.size(), sig);
    add_cycles(r, starts, options.coherence, d, coherence_frames);
    add_band_powers(seg, sig, d);
    d.segments.push_back(std::move(seg));
  }
  if (d.cycles.empty())
    throw std::invalid_argument("condition " + info.name + ": no complete engine cycle with microphone data");
  d.periodic_share.assign(d.bands, std::nan(""));
  d.fluct_coherence.assign(d.bands, std::nan(""));
  d.coherent_fraction.assign(d.bands, std::nan(""));
  if (options.coherence && coherence_frames.u.size() >= 4) cycle_coherence(coherence_frames, probe.bands(), d);
  return d;
}

BandDataset make_dataset(std::vector<ConditionData> conditions) {
  BandDataset ds;
  const dsp::ThirdOctaveBank probe(kDatasetRateHz, 1);
  ds.bands = probe.bands();
  ds.conditions = std::move(conditions);
  const std::size_t nb = ds.bands.size();
  ds.line_free.assign(ds.conditions.size() * nb, false);
  for (std::size_t k = 0; k < ds.conditions.size(); ++k) {
    const double f0 = ds.conditions[k].mean_speed_rpm() / 120.0;  // cycle frequency
    for (std::size_t b = 0; b < nb; ++b) {
      const double lo = ds.bands[b].lower_edge_hz, hi = std::min(ds.bands[b].upper_edge_hz, kDatasetRateHz / 2);
      const double first = std::max(1.0, std::ceil(lo / f0));
      ds.line_free[k * nb + b] = f0 > 0 && first * f0 >= hi;
    }
  }
  judge_pressure_floors(ds);
  return ds;
}

}  // namespace noisemon::model::fit
