// Predictions of a condition by an extended model: the time-domain re-simulation of the block (its second mode
// included), times the other extensions' factors from the frequency-domain view, less what the pressure chain's
// noise drove, plus the additive noise.
#include <algorithm>
#include <cmath>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit {
namespace {

using namespace band_fit_internal;

constexpr double kObservableShare = 0.1;  // a cell's per-cycle value is never taken below this share of the full one

// The structural variables of a model relative to an anchor's block (no derivatives).
void model_struct(const ExtendedModel& model, const BlockParams& anchor_block, double* s) {
  const ExtensionParams& e = model.ext;
  s[kSK1] = std::log(model.block.k1 / anchor_block.k1);
  s[kSB1] = std::log(model.block.b1 / anchor_block.b1);
  s[kSC0] = std::log(model.block.c0 / anchor_block.c0);
  s[kSC1] = std::log(model.block.c1 / anchor_block.c1);
  s[kSModeDb] = e.mode_db;
  s[kSModeLogF] = std::log(e.mode_hz / 1000.0);
  s[kSModeLogQ] = std::log(e.mode_q);
  s[kSModePhase] = mode_phase_rad(e);
  s[kSSpeedGain] = e.speed_gain_db_per_krpm;
  s[kSSpeedShift] = e.speed_shift_per_krpm;
  s[kSTnLogD] = e.transducer_density > 0 ? std::log10(e.transducer_density) : -300.0;
  s[kSTnSlope] = e.transducer_slope;
  s[kSLockExp] = e.locked_speed_exp;
}

// Per crank window: the condition's mean share of the cycle's frames.
std::vector<double> window_fractions(const ConditionData& cond) {
  std::vector<double> frac(kW, 0.0);
  double tot = 0.0;
  for (std::size_t cy = 0; cy < cond.cycle_count(); ++cy)
    for (std::size_t w = 0; w < kW; ++w) {
      frac[w] += cond.win_frames[cy * kW + w];
      tot += cond.win_frames[cy * kW + w];
    }
  for (double& x : frac) x /= tot;
  return frac;
}

// Per band: the mean over the first `cycles` cycles of the additive part apply_factors gives each cycle (its windows'
// additive levels weighted by the cycle's own window lengths).
std::vector<double> additive_cycle_mean(const ConditionFactors& f, const ConditionData& cond, std::size_t cycles) {
  const std::size_t nb = f.add.size();
  std::vector<double> mean(nb, 0.0);
  for (std::size_t c = 0; c < cycles; ++c) {
    double tot = 0.0;
    for (std::size_t w = 0; w < kW; ++w) tot += cond.win_frames[c * kW + w];
    for (std::size_t b = 0; b < nb; ++b)
      for (std::size_t w = 0; w < kW; ++w)
        mean[b] += f.add_win[b * kW + w] * cond.win_frames[c * kW + w] / tot / static_cast<double>(cycles);
  }
  return mean;
}

}  // namespace

ConditionFactors extension_factors(const BandDataset& data, std::size_t k, const ConditionSpectrum& spec,
                                   const BlockParams& anchor_block, const ExtendedModel& model) {
  const std::size_t nb = data.band_count();
  const ConditionData& cond = data.conditions[k];
  const ExtensionParams& e = model.ext;
  Layout L;
  L.anchor = anchor_block;
  L.fixed = model.block;
  L.on = model.on;
  L.nbands = nb;
  CondSetup c;
  c.spec = &spec;
  c.dn_krpm = (cond.mean_speed_rpm() - e.speed_ref_rpm) / 1000.0;
  c.speed_ratio = cond.mean_speed_rpm() / e.speed_ref_rpm;
  std::vector<std::size_t> all(nb);
  for (std::size_t b = 0; b < nb; ++b) all[b] = b;
  std::vector<double> with, bare, noise;
  double s[kStruct] = {};
  model_struct(model, anchor_block, s);
  band_sums(L, c, s, all, with, &noise);
  Layout Lb = L;
  Lb.on = ExtensionSet{};
  double s0[kStruct] = {};
  band_sums(Lb, c, s0, all, bare);
  ConditionFactors f;
  f.mult.assign(nb, 1.0);
  f.sub.assign(nb, 0.0);
  f.add.assign(nb, 0.0);
  f.add_win.assign(nb * kW, 0.0);
  const double gain = L.on.speed ? std::pow(10.0, e.speed_gain_db_per_krpm * c.dn_krpm / 10.0) : 1.0;
  const double lscale = L.on.locked ? std::pow(c.speed_ratio, e.locked_speed_exp) : 1.0;
  const std::vector<double> frac = window_fractions(cond);
  for (std::size_t b = 0; b < nb; ++b) {
    f.mult[b] = (bare[b] > 0 ? with[b] / bare[b] : 1.0) * gain;
    if (!noise.empty()) f.sub[b] = noise[b] * gain;
    for (std::size_t w = 0; w < kW; ++w) {
      double a = 0.0;
      if (L.on.stationary && b < e.stationary_ms.size()) a += e.stationary_ms[b];
      if (L.on.locked && b * kW + w < e.locked_ms.size()) a += lscale * e.locked_ms[b * kW + w];
      f.add_win[b * kW + w] = a;
      f.add[b] += a * frac[w];
    }
  }
  return f;
}

void apply_factors(const ConditionFactors& f, const ConditionData& cond, std::vector<double>& cycle_ms,
                   std::vector<double>* win_ms, std::vector<char>* upper, std::vector<char>* upper_win) {
  const std::size_t nb = cond.bands, nc = cycle_ms.size() / nb;
  const bool windows = win_ms && !win_ms->empty();
  std::vector<double> mean(nb, 0.0), wmean(nb * kW, 0.0);
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t b = 0; b < nb; ++b) {
      mean[b] += cycle_ms[c * nb + b] / static_cast<double>(nc);
      if (windows)
        for (std::size_t w = 0; w < kW; ++w)
          wmean[b * kW + w] += (*win_ms)[(c * kW + w) * nb + b] / static_cast<double>(nc);
    }
  // Censoring is decided on the condition's means (see kFloorShare).
  std::vector<char> cb(nb, 0), cw(nb * kW, 0);
  for (std::size_t b = 0; b < nb; ++b) {
    if (f.sub[b] == 0.0) continue;
    const auto at_floor = [&](const std::vector<char>& flags, std::size_t i) { return i < flags.size() && flags[i]; };
    cb[b] = f.sub[b] > kFloorShare * mean[b] * f.mult[b] || at_floor(cond.info.floor_limited_band, b);
    if (windows)
      for (std::size_t w = 0; w < kW; ++w)
        cw[b * kW + w] = f.sub[b] > kFloorShare * wmean[b * kW + w] * f.mult[b] ||
                         at_floor(cond.info.floor_limited_window, b * kW + w);
  }
  // A cell's value: the full prediction less the noise-driven part (never below kObservableShare of it), or, where
  // censored, that less part plus the allowance.
  const auto clean = [](double full, double cut, bool limited) {
    return limited ? std::max(full - cut, 0.0) + kFloorAllowance * cut : std::max(full - cut, kObservableShare * full);
  };
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t b = 0; b < nb; ++b) {
      // The cycle's additive share from its own window lengths.
      double add = 0.0, tot = 0.0;
      for (std::size_t w = 0; w < kW; ++w) {
        const double fr = cond.win_frames[c * kW + w];
        add += f.add_win[b * kW + w] * fr;
        tot += fr;
      }
      double& x = cycle_ms[c * nb + b];
      x = clean(x * f.mult[b], f.sub[b], cb[b]) + add / tot;
      if (windows)
        for (std::size_t w = 0; w < kW; ++w) {
          double& y = (*win_ms)[(c * kW + w) * nb + b];
          y = clean(y * f.mult[b], f.sub[b], cw[b * kW + w]) + f.add_win[b * kW + w];
        }
    }
  if (upper) *upper = cb;
  if (upper_win) *upper_win = cw;
}

ConditionPrediction predict_condition(const BandDataset& data, std::size_t k, const ExtendedModel& model, bool windows,
                                      std::size_t cycles) {
  ConditionPrediction p;
  // The second mode runs in the time domain here (exact per crank window too, where a band factor is not: the
  // spectrum inside a band differs between the combustion window and the rest of the cycle).
  simulate_condition(data.conditions[k], model.block, cycles, p.cycle_ms, windows ? &p.win_ms : nullptr,
                     model.on.second_mode ? &model.ext : nullptr);
  ExtendedModel rest = model;
  rest.on.second_mode = false;
  const ExtensionSet& on = rest.on;
  const bool floor = !data.conditions[k].info.floor_density.empty();
  if (!(on.speed || on.transducer || on.stationary || on.locked || floor)) return p;
  const ConditionSpectrum spec = condition_spectrum(data, k, cycles);
  const ConditionFactors f = extension_factors(data, k, spec, model.block, rest);
  apply_factors(f, data.conditions[k], p.cycle_ms, windows ? &p.win_ms : nullptr, &p.upper, &p.upper_win);
  p.additive_ms = additive_cycle_mean(f, data.conditions[k], p.cycle_ms.size() / data.band_count());
  return p;
}

}  // namespace noisemon::model::fit
