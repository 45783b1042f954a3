// One surrogate problem's parameter layout, its view of each training condition, its starting values and the
// model its values stand for.
#include <algorithm>
#include <cmath>
#include <limits>

#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit::band_fit_internal {
namespace {

// The crank-window part of a condition's view (locked noise): per window band the measured (gain-corrected) and
// the anchor's window means, and which windows have the pressure within their floor's margin.
void add_window_bands(const BandDataset& data, const Anchor& anchor, std::size_t ai, const FitSetup& setup,
                      const ExtendedModel& model, CondSetup& c) {
  const ConditionData& cond = data.conditions[c.k];
  const std::size_t nb = data.band_count();
  const std::size_t ncyc = anchor.cycle_ms[ai].size() / nb;
  const std::vector<char> wcap = window_capable_bands(data, setup.train);
  std::vector<double> fr(kW, 0.0);
  double tot = 0.0;
  for (std::size_t cy = 0; cy < ncyc; ++cy)
    for (std::size_t w = 0; w < kW; ++w) {
      fr[w] += cond.win_frames[cy * kW + w];
      tot += cond.win_frames[cy * kW + w];
    }
  for (std::size_t w = 0; w < kW; ++w) c.frac[w] = fr[w] / tot;
  const std::vector<char>& at_floor = cond.info.floor_limited_window;
  for (std::size_t b : c.bands) {
    if (!wcap[b]) continue;
    std::vector<double> wm(kW, 0.0), wa(kW, 0.0);
    bool ok = true;
    for (std::size_t w = 0; w < kW; ++w) {
      double corr_num = 0.0, corr_den = 0.0;
      for (std::size_t cy = 0; cy < ncyc; ++cy) {
        wm[w] += cond.win_ms[(cy * kW + w) * nb + b];
        wa[w] += anchor.win_ms[ai][(cy * kW + w) * nb + b];
        corr_num += measured_ms(cond, cy, b, model);
        corr_den += cond.mic_avg_ms(cy, b);
      }
      wm[w] *= corr_den > 0 ? corr_num / corr_den : 1.0;
      wm[w] /= static_cast<double>(ncyc);
      wa[w] /= static_cast<double>(ncyc);
      if (!(wm[w] > 0.0) || !(wa[w] > 0.0)) ok = false;
    }
    if (!ok) continue;
    c.wbands.push_back(b);
    c.wmeas.insert(c.wmeas.end(), wm.begin(), wm.end());
    c.wanchor.insert(c.wanchor.end(), wa.begin(), wa.end());
    for (std::size_t w = 0; w < kW; ++w) c.wfloor.push_back(b * kW + w < at_floor.size() && at_floor[b * kW + w]);
  }
}

// Starting values of the additive noise: from the start model, or from the excess the start model leaves (a small
// share when none).
void initial_additive_values(const Layout& L, const ExtensionParams& e, const std::vector<CondSetup>& conds,
                             Values& v) {
  v.stat.assign(L.add_bands.size(), std::log(1e-4));
  v.locked.assign(L.add_bands.size(), {});
  for (std::size_t s = 0; s < L.add_bands.size(); ++s) {
    const std::size_t b = L.add_bands[s];
    double excess = 0.0;
    int n = 0;
    for (const CondSetup& c : conds)
      for (std::size_t i = 0; i < c.bands.size(); ++i)
        if (c.bands[i] == b) {
          excess += std::max(0.0, c.meas[i] - c.anchor[i]);
          ++n;
        }
    excess = n > 0 ? excess / n : 0.0;
    const double share = std::clamp(excess / L.add_ref[s], 1e-4, 10.0);
    const double given_stat = b < e.stationary_ms.size() ? e.stationary_ms[b] : 0.0;
    v.stat[s] = std::log(given_stat > 0 ? std::clamp(given_stat / L.add_ref[s], kAdditiveFloor * 10, kAdditiveCeil / 10)
                                        : share);
    const std::size_t nw = L.add_windowed[s] ? kW : 1;
    v.locked[s].assign(nw, std::log(share));
    if (b * kW + kW <= e.locked_ms.size()) {
      for (std::size_t w = 0; w < nw; ++w) {
        double m = 0.0;
        if (nw == kW)
          m = e.locked_ms[b * kW + w];
        else
          for (std::size_t ww = 0; ww < kW; ++ww) m += e.locked_ms[b * kW + ww] / kW;
        if (m > 0) v.locked[s][w] = std::log(std::clamp(m / L.add_ref[s], kAdditiveFloor * 10, kAdditiveCeil / 10));
      }
    }
  }
}

}  // namespace

Layout make_layout(const BandDataset& data, const BlockParams& anchor, const BlockParams& start,
                   const std::vector<BlockParam>& free, bool taylor, const ExtensionSet& on,
                   const std::vector<std::size_t>& conds, const std::vector<std::vector<char>>& scored) {
  Layout L;
  L.anchor = anchor;
  L.fixed = start;
  L.on = on;
  L.taylor = taylor;
  L.nbands = data.band_count();
  for (BlockParam p : free) L.lin_free.push_back(struct_index(p));
  if (on.stationary || on.locked) {
    const std::vector<char> wcap = window_capable_bands(data, conds);
    for (std::size_t b = 0; b < L.nbands; ++b) {
      double ref = 0.0;
      int n = 0;
      for (std::size_t k : conds)
        if (scored[k][b]) {
          const ConditionData& c = data.conditions[k];
          for (std::size_t cy = 0; cy < c.cycle_count(); ++cy) ref += c.mic_avg_ms(cy, b);
          n += static_cast<int>(c.cycle_count());
        }
      if (n == 0) continue;
      L.add_bands.push_back(b);
      L.add_windowed.push_back(on.locked && wcap[b]);
      L.add_ref.push_back(ref / n);
    }
  }
  return L;
}

CondSetup make_cond_setup(const BandDataset& data, const Anchor& anchor, std::size_t ai, const Layout& L,
                          const FitSetup& setup, const ExtendedModel& model, double ref_rpm) {
  const std::size_t k = anchor.conditions[ai];
  const ConditionData& cond = data.conditions[k];
  CondSetup c;
  c.k = k;
  c.spec = &anchor.spectra[ai];
  const std::size_t nb = data.band_count();
  const std::size_t ncyc = anchor.cycle_ms[ai].size() / nb;
  for (std::size_t b = 0; b < nb; ++b) {
    if (!setup.scored[k][b]) continue;
    double m = 0.0, a = 0.0;
    for (std::size_t cy = 0; cy < ncyc; ++cy) {
      m += measured_ms(cond, cy, b, model);
      a += anchor.cycle_ms[ai][cy * nb + b];
    }
    if (!(m > 0.0) || !(a > 0.0) || c.spec->band_taps[b].empty()) continue;
    c.bands.push_back(b);
    c.meas.push_back(m / static_cast<double>(ncyc));
    c.anchor.push_back(a / static_cast<double>(ncyc));
    if (L.taylor) {
      const std::size_t np = anchor.jac_params.size();
      for (std::size_t i = 0; i < np; ++i) c.jac.push_back(anchor.jac[ai][b * np + i]);
    }
  }
  c.f0.resize(c.bands.size());
  {
    Layout bare = L;
    bare.on = ExtensionSet{};
    bare.fixed = L.anchor;
    bare.lin_free.clear();
    bare.taylor = false;
    const double s[kStruct] = {};
    band_sums(bare, c, s, c.bands, c.f0);
  }
  c.frac.assign(kW, 1.0 / kW);
  if (L.on.locked && !anchor.win_ms[ai].empty()) add_window_bands(data, anchor, ai, setup, model, c);
  c.dn_krpm = (cond.mean_speed_rpm() - ref_rpm) / 1000.0;
  c.speed_ratio = cond.mean_speed_rpm() / ref_rpm;
  c.weight = c.bands.empty() ? 0.0 : 1.0 / std::sqrt(static_cast<double>(c.bands.size()));
  c.wweight = c.wbands.empty() ? 0.0 : std::sqrt(setup.window_weight / static_cast<double>(c.wbands.size() * kW));
  return c;
}

Values initial_values(const Layout& L, const ExtendedModel& start, const std::vector<CondSetup>& conds) {
  Values v;
  for (int idx : L.lin_free) {
    const BlockParam p = param_of_struct(idx);
    v.lin.push_back(std::log(param_value(start.block, p) / param_value(L.anchor, p)));
  }
  const ExtensionParams& e = start.ext;
  v.mode = {e.mode_db, std::log(e.mode_hz / 1000.0), std::log(e.mode_q), mode_phase_rad(e)};
  v.speed = {e.speed_gain_db_per_krpm, e.speed_shift_per_krpm};
  v.tn = {e.transducer_density > 0 ? std::log10(e.transducer_density) : 0.0, e.transducer_slope};
  if (!(e.transducer_density > 0) && L.on.transducer) {
    // Start far below the quietest part of the pressure spectrum above 1 kHz (the noise must be found, not assumed).
    double lowest = std::numeric_limits<double>::infinity();
    for (const CondSetup& c : conds)
      for (std::size_t j = 0; j < c.spec->f_hz.size(); ++j)
        if (c.spec->f_hz[j] > 1000.0) lowest = std::min(lowest, c.spec->s[j] / c.spec->df_hz[j]);
    v.tn[0] = std::isfinite(lowest) && lowest > 0 ? std::log10(lowest) - 2.0 : -6.0;
  }
  v.lexp = {e.locked_speed_exp};
  initial_additive_values(L, e, conds, v);
  return v;
}

ExtendedModel model_from_values(const Layout& L, const Values& v, const ExtendedModel& start) {
  ExtendedModel m = start;
  m.block = L.fixed;
  for (std::size_t i = 0; i < L.lin_free.size(); ++i) {
    const BlockParam p = param_of_struct(L.lin_free[i]);
    set_param(m.block, p, param_value(L.anchor, p) * std::exp(v.lin[i]));
  }
  ExtensionParams& e = m.ext;
  if (L.on.second_mode) {
    e.mode_db = v.mode[0];
    e.mode_hz = 1000.0 * std::exp(v.mode[1]);
    e.mode_q = std::exp(v.mode[2]);
    e.mode_phase_deg = std::remainder(v.mode[3] * 180.0 / kPi, 360.0);
    if (e.mode_phase_deg <= -180.0) e.mode_phase_deg += 360.0;
  }
  if (L.on.speed) {
    e.speed_gain_db_per_krpm = v.speed[0];
    e.speed_shift_per_krpm = v.speed[1];
  }
  if (L.on.transducer) {
    e.transducer_density = std::pow(10.0, v.tn[0]);
    e.transducer_slope = v.tn[1];
  }
  if (L.on.stationary) {
    e.stationary_ms.assign(L.nbands, 0.0);
    for (std::size_t s = 0; s < L.add_bands.size(); ++s)
      e.stationary_ms[L.add_bands[s]] = L.add_ref[s] * std::exp(v.stat[s]);
  }
  if (L.on.locked) {
    e.locked_ms.assign(L.nbands * kW, 0.0);
    for (std::size_t s = 0; s < L.add_bands.size(); ++s)
      for (std::size_t w = 0; w < kW; ++w)
        e.locked_ms[L.add_bands[s] * kW + w] = L.add_ref[s] * std::exp(v.locked[s][L.add_windowed[s] ? w : 0]);
    e.locked_speed_exp = v.lexp[0];
  }
  return m;
}

}  // namespace noisemon::model::fit::band_fit_internal
