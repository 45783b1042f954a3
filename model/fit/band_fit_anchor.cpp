// The time-domain re-simulation of the block model: one condition through the bank (simulate_condition), and the
// anchors the surrogate fits move from (make_anchor).
#include <algorithm>
#include <cmath>

#include "model/block_model.hpp"
#include "model/engine/effects.hpp"
#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit {
namespace band_fit_internal {
namespace {

constexpr std::size_t kPrimeFrames = 512;  // the block model's modes decay within a millisecond

}  // namespace

void simulate_condition(const ConditionData& cond, const BlockParams& params, std::size_t cycles,
                        std::vector<double>& cycle_ms, std::vector<double>* win_ms, const ExtensionParams* mode) {
  const std::size_t total = cond.cycle_count();
  const std::size_t want = (cycles == 0 || cycles > total) ? total : cycles;
  cycle_ms.clear();
  if (win_ms) win_ms->clear();
  std::vector<double> u, y, part, wpart;
  std::size_t done = 0;
  for (const PreparedSegment& seg : cond.segments) {
    if (done >= want) break;
    const std::size_t nc = std::min(segment_cycles(seg), want - done);
    const std::size_t frames = segment_frames(seg, nc);
    BlockModel bm(params, kDatasetRateHz);
    const std::size_t lat = bm.latency_samples();
    // Settle at the first pressure (its static equilibrium), as the live pipeline does.
    u.assign(kPrimeFrames, seg.pressure_pa[0]);
    y.resize(kPrimeFrames);
    bm.process(u.data(), y.data(), kPrimeFrames);
    u.assign(seg.pressure_pa.begin(), seg.pressure_pa.begin() + static_cast<std::ptrdiff_t>(frames));
    u.resize(frames + lat, seg.pressure_pa[frames - 1]);
    y.resize(u.size());
    bm.process(u.data(), y.data(), u.size());
    // Output j describes input j - latency; remove the static deflection (mean of the first cycle).
    const std::size_t len0 = seg.cycle_starts[1] - seg.cycle_starts[0];
    double mean = 0.0;
    const std::size_t nmean = std::min(len0, frames);
    for (std::size_t i = 0; i < nmean; ++i) mean += y[i + lat];
    mean /= static_cast<double>(nmean);
    for (std::size_t i = 0; i < frames; ++i) y[i] = y[i + lat] - mean;
    if (mode) {
      engine::Effects e;
      e.second_mode_db = mode->mode_db;
      e.second_mode_hz = mode->mode_hz;
      e.second_mode_q = mode->mode_q;
      e.second_mode_phase_deg = mode->mode_phase_deg;
      engine::SecondModeFilter(e, kDatasetRateHz).process(y.data(), frames);
    }
    segment_band_powers(seg, y.data(), 1, nc, part, win_ms ? &wpart : nullptr);
    cycle_ms.insert(cycle_ms.end(), part.begin(), part.end());
    if (win_ms) win_ms->insert(win_ms->end(), wpart.begin(), wpart.end());
    done += nc;
  }
}

}  // namespace band_fit_internal

using namespace band_fit_internal;

Anchor make_anchor(const BandDataset& data, const BlockParams& block, const std::vector<std::size_t>& conditions,
                   std::size_t cycles, bool windows, const std::vector<BlockParam>& jac_params) {
  Anchor a;
  a.block = block;
  a.conditions = conditions;
  a.cycles = cycles;
  a.cycle_ms.resize(conditions.size());
  a.win_ms.resize(conditions.size());
  a.jac_params = jac_params;
  a.jac.resize(conditions.size());
  const std::size_t nb = data.band_count(), np = jac_params.size();
  const double h = std::log(1.03);
  std::vector<double> plus;
  for (std::size_t i = 0; i < conditions.size(); ++i) {
    simulate_condition(data.conditions[conditions[i]], block, cycles, a.cycle_ms[i], windows ? &a.win_ms[i] : nullptr);
    a.spectra.push_back(condition_spectrum(data, conditions[i], cycles));
    if (np == 0) continue;
    const std::size_t nc = a.cycle_ms[i].size() / nb;
    std::vector<double> base(nb, 0.0);
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t b = 0; b < nb; ++b) base[b] += a.cycle_ms[i][c * nb + b];
    a.jac[i].assign(nb * np, 0.0);
    for (std::size_t j = 0; j < np; ++j) {
      BlockParams q = block;
      set_param(q, jac_params[j], param_value(block, jac_params[j]) * std::exp(h));
      simulate_condition(data.conditions[conditions[i]], q, cycles, plus, nullptr);
      for (std::size_t b = 0; b < nb; ++b) {
        double sp = 0.0;
        for (std::size_t c = 0; c < nc; ++c) sp += plus[c * nb + b];
        a.jac[i][b * np + j] = (sp > 0 && base[b] > 0) ? std::log(sp / base[b]) / h : 0.0;
      }
    }
  }
  return a;
}

}  // namespace noisemon::model::fit
