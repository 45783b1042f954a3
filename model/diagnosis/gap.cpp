// The held-out gap of one condition (diagnosis.hpp): the thesis band gap, the microphone calibration residual
// and the crank-window gap, and the bootstrap draws over cycles that give its noise.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kMicSpreadFloorDb = 0.1;  // robust spread of the array never taken below this
constexpr double kMicOutlierSigmas = 3.0;

// Weighted cycle sums of the measured (m) and predicted (q) mean squares, per band and, in the fast bands, per
// band * W ([b * W + w]); n: the sum of the weights.
struct CycleSums {
  std::vector<double> m, q, mw, qw;
  double n = 0.0;
};

CycleSums cycle_sums(const fit::ConditionData& d, const Measured& ms, const fit::ConditionPrediction& p,
                     const std::vector<char>& fast, const std::vector<int>* counts) {
  const std::size_t nb = d.bands, nc = d.cycle_count();
  CycleSums s;
  s.m.assign(nb, 0.0);
  s.q.assign(nb, 0.0);
  s.mw.assign(nb * kW, 0.0);
  s.qw.assign(nb * kW, 0.0);
  for (std::size_t c = 0; c < nc; ++c) {
    const double w = counts ? (*counts)[c] : 1.0;
    if (w == 0) continue;
    s.n += w;
    for (std::size_t b = 0; b < nb; ++b) {
      s.m[b] += w * ms.meas[c * nb + b];
      s.q[b] += w * p.cycle_ms[c * nb + b];
      if (!fast[b]) continue;
      for (std::size_t ww = 0; ww < kW; ++ww) {
        s.mw[b * kW + ww] += w * ms.win[(c * kW + ww) * nb + b];
        s.qw[b * kW + ww] += w * p.win_ms[(c * kW + ww) * nb + b];
      }
    }
  }
  return s;
}

// Sampling variance of a cycle-averaged gap 10 log10(sum m / sum q) from the cycle-to-cycle scatter (delta
// method): subtracting it from the squared gap leaves an unbiased estimate of the squared systematic gap, so the
// noise of a few cycles does not count as disagreement. `add`: a per-cycle constant added to the prediction.
template <class GetM, class GetQ>
double gap_variance(GetM get_m, GetQ get_q, double msum, double qsum, double add, double n, std::size_t nc,
                    const std::vector<int>* counts) {
  constexpr double kDb2 = (10.0 / std::numbers::ln10) * (10.0 / std::numbers::ln10);
  if (n < 2) return 0.0;
  const double mbar = msum / n, qbar = (qsum + n * add) / n;
  double s1 = 0.0, s2 = 0.0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double w = counts ? (*counts)[c] : 1.0;
    if (w == 0) continue;
    const double r = get_m(c) / mbar - (get_q(c) + add) / qbar;
    s1 += w * r;
    s2 += w * r * r;
  }
  const double var = (s2 - s1 * s1 / n) / (n - 1.0);
  return kDb2 * std::max(0.0, var) / n;
}

bool band_counts(const CycleSums& s, const std::vector<char>& scored, std::size_t b) {
  return scored[b] && s.m[b] > 0 && s.q[b] > 0;
}

// Part 1, the thesis band gap: sum of squared cycle-averaged band gaps less their sampling variance (upper-bound
// bands: only a measurement above the bound counts). Returns the number of bands counted.
int band_part(const fit::ConditionData& d, const Measured& ms, const fit::ConditionPrediction& p,
              const std::vector<char>& scored, const CycleSums& s, const std::vector<int>* counts, Parts& parts,
              ScoreDetail* detail) {
  const std::size_t nb = d.bands, nc = d.cycle_count();
  int nbands = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    if (!band_counts(s, scored, b)) continue;
    const bool ub = !p.upper.empty() && p.upper[b];
    const double g = ub ? std::max(0.0, db(s.m[b] / s.q[b])) : db(s.m[b] / s.q[b]);
    if (!ub)
      parts.band_ms -=
          gap_variance([&](std::size_t c) { return ms.meas[c * nb + b]; },
                       [&](std::size_t c) { return p.cycle_ms[c * nb + b]; }, s.m[b], s.q[b], 0.0, s.n, nc, counts);
    parts.band_ms += g * g;
    ++nbands;
    if (detail) detail->gaps[b] = g;
  }
  return nbands;
}

// Part 3, the crank-window gap in the fast counted bands, against the prediction plus the stationary floor.
// Returns the number of cells counted; wsum / wcount: per window, the sum and number of its cells' gaps.
int window_part(const fit::ConditionData& d, const Measured& ms, const fit::ConditionPrediction& p,
                const std::vector<char>& scored, const std::vector<char>& fast, const std::vector<double>& floor,
                const CycleSums& s, const std::vector<int>* counts, Parts& parts, ScoreDetail* detail,
                std::vector<double>& wsum, std::vector<int>& wcount) {
  const std::size_t nb = d.bands, nc = d.cycle_count();
  int nwin = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    if (!band_counts(s, scored, b) || !fast[b]) continue;
    for (std::size_t ww = 0; ww < kW; ++ww) {
      const double den = s.qw[b * kW + ww] + s.n * floor[b];
      if (!(s.mw[b * kW + ww] > 0) || !(den > 0)) continue;
      const bool uw = !p.upper_win.empty() && p.upper_win[b * kW + ww];
      const double h = uw ? std::max(0.0, db(s.mw[b * kW + ww] / den)) : db(s.mw[b * kW + ww] / den);
      parts.window_ms += h * h;
      if (!uw)
        parts.window_ms -= gap_variance([&](std::size_t c) { return ms.win[(c * kW + ww) * nb + b]; },
                                        [&](std::size_t c) { return p.win_ms[(c * kW + ww) * nb + b]; },
                                        s.mw[b * kW + ww], s.qw[b * kW + ww], floor[b], s.n, nc, counts);
      ++nwin;
      if (detail) detail->cell[ww * nb + b] = h;
      wsum[ww] += h;
      ++wcount[ww];
    }
  }
  return nwin;
}

}  // namespace

double db(double ratio) { return 10.0 * std::log10(ratio); }

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

Measured measured_side(const fit::ConditionData& d, const fit::ExtendedModel& m) {
  const std::size_t nb = d.bands, M = d.mics, nc = d.cycle_count();
  Measured r;
  r.meas.resize(nc * nb);
  r.mic = d.mic_ms;
  r.win = d.win_ms;
  const bool gains = m.on.mic_gain && m.ext.mic_gain_db.size() == M;
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t b = 0; b < nb; ++b) {
      double s = 0.0, raw = 0.0;
      for (std::size_t mi = 0; mi < M; ++mi) {
        double& x = r.mic[(c * M + mi) * nb + b];
        raw += x;
        if (gains) x *= std::pow(10.0, -m.ext.mic_gain_db[mi] / 10.0);
        s += x;
      }
      r.meas[c * nb + b] = s / static_cast<double>(M);
      if (gains && raw > 0)
        for (std::size_t w = 0; w < kW; ++w) r.win[(c * kW + w) * nb + b] *= s / raw;
    }
  return r;
}

std::vector<double> mic_offsets(const fit::ConditionData& d, const Measured& ms, const std::vector<char>& scored,
                                const std::vector<int>* counts) {
  const std::size_t nb = d.bands, M = d.mics, nc = d.cycle_count();
  std::vector<double> mic_sum(M * nb, 0.0), avg(nb, 0.0), off(M, 0.0);
  for (std::size_t c = 0; c < nc; ++c) {
    const double w = counts ? (*counts)[c] : 1.0;
    if (w == 0) continue;
    for (std::size_t m = 0; m < M; ++m)
      for (std::size_t b = 0; b < nb; ++b) mic_sum[m * nb + b] += w * ms.mic[(c * M + m) * nb + b];
    for (std::size_t b = 0; b < nb; ++b) avg[b] += w * ms.meas[c * nb + b];
  }
  int n = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    if (!scored[b] || !(avg[b] > 0)) continue;
    ++n;
    for (std::size_t m = 0; m < M; ++m) off[m] += mic_sum[m * nb + b] > 0 ? db(mic_sum[m * nb + b] / avg[b]) : 0.0;
  }
  for (double& o : off) o = n > 0 ? o / n : 0.0;
  return off;
}

std::vector<double> mic_outliers(const std::vector<double>& off) {
  const double med = median(off);
  std::vector<double> dev;
  for (double o : off) dev.push_back(std::abs(o - med));
  const double s = std::max(kMicSpreadFloorDb, 1.4826 * median(dev));
  std::vector<double> t(off.size());
  for (std::size_t i = 0; i < off.size(); ++i) {
    const double x = off[i] - med;
    t[i] = std::copysign(std::max(0.0, std::abs(x) - kMicOutlierSigmas * s), x);
  }
  return t;
}

Parts score_condition(const fit::ConditionData& d, const Measured& ms, const fit::ConditionPrediction& p,
                      const std::vector<char>& scored, const std::vector<char>& fast, const std::vector<double>& floor,
                      const std::vector<int>* counts, ScoreDetail* detail) {
  const std::size_t nb = d.bands;
  const CycleSums s = cycle_sums(d, ms, p, fast, counts);
  Parts parts;
  if (detail) {
    detail->gaps.assign(nb, kNaN);
    detail->window.assign(kW, 0.0);
    detail->cell.assign(kW * nb, kNaN);
  }
  std::vector<double> wsum(kW, 0.0);
  std::vector<int> wcount(kW, 0);
  const int nbands = band_part(d, ms, p, scored, s, counts, parts, detail);
  const int nwin = window_part(d, ms, p, scored, fast, floor, s, counts, parts, detail, wsum, wcount);
  parts.band_ms = nbands > 0 ? std::max(0.0, parts.band_ms / nbands) : 0.0;
  parts.window_ms = nwin > 0 ? std::max(0.0, parts.window_ms / nwin) : 0.0;
  // Part 2, the microphone calibration residual.
  const std::vector<double> t = mic_outliers(mic_offsets(d, ms, scored, counts));
  for (double x : t) parts.mic += x * x;
  if (detail) {
    detail->mic_resid = t;
    for (std::size_t ww = 0; ww < kW; ++ww) detail->window[ww] = wcount[ww] > 0 ? wsum[ww] / wcount[ww] : kNaN;
  }
  return parts;
}

void draw_bootstrap(Context& cx) {
  const fit::BandDataset& data = *cx.data;
  std::mt19937_64 rng(cx.opt->seed);
  cx.counts.resize(static_cast<std::size_t>(std::max(0, cx.opt->bootstrap)));
  for (auto& rep : cx.counts) {
    rep.resize(cx.heldout.size());
    for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
      const std::size_t nc = data.conditions[cx.heldout[h]].cycle_count();
      rep[h].assign(nc, 0);
      std::uniform_int_distribution<std::size_t> pick(0, nc - 1);
      for (std::size_t i = 0; i < nc; ++i) ++rep[h][pick(rng)];
    }
  }
}

void set_information_criterion(ModelScore& m) {
  int n = 0;
  for (const auto& rows : {&m.gaps, &m.cell_gaps, &m.mic_resid})
    for (const std::vector<double>& row : *rows)
      n += static_cast<int>(std::count_if(row.begin(), row.end(), [](double x) { return std::isfinite(x); }));
  m.heldout_cells = n;
  const double gap2 = std::max(m.heldout_gap_db * m.heldout_gap_db, 1e-12);
  m.information_criterion = n > 0 ? n * std::log(gap2) + m.parameters * std::log(static_cast<double>(n)) : 0.0;
}

}  // namespace noisemon::model::diagnosis
