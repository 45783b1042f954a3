// The residuals of one training condition in the surrogate: the anchor's time-domain band powers moved by the
// shortcut's ratio F_b(theta) / F_b(theta_anchor) (or, for nonlinear blocks, by the anchor's exact Jacobian), less
// what the pressure chain's noise drove, plus the additive noise; compared in dB with the measurement.
#include <algorithm>
#include <cmath>
#include <string>

#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit::band_fit_internal {
namespace {

// F_b of the condition's scored bands at the structural variables s, and its noise-driven part. Taylor mode: the
// extensions on the anchor's block; the block's own change from the exact Jacobian.
void structural_sums(const Layout& L, const CondSetup& c, const Jet* s, std::vector<Jet>& sums,
                     std::vector<Jet>& noise) {
  if (!L.taylor) {
    band_sums(L, c, s, c.bands, sums, &noise);
    return;
  }
  Jet se[kStruct];
  for (int i = 0; i < kStruct; ++i) se[i] = s[i];
  for (int i : {kSK1, kSB1, kSC0, kSC1, kSK3, kSB3}) se[i] = Jet(0.0);
  band_sums(L, c, se, c.bands, sums, &noise);
  const std::size_t np = L.lin_free.size();
  for (std::size_t i = 0; i < c.bands.size(); ++i) {
    Jet e = Jet(0.0);
    for (std::size_t j = 0; j < np; ++j) e += c.jac[i * np + j] * s[L.lin_free[j]];
    sums[i] *= exp(e);
    if (!noise.empty()) noise[i] *= exp(e);
  }
}

// A prediction less its noise-driven part; within the floor's margin the result is an upper bound (censored).
struct Clean {
  Jet value;
  bool upper = false;
};

Clean minus_noise(const Jet& full, const Jet& cut, bool at_floor) {
  const bool limited = cut.a > 0.0 && (at_floor || cut.a > kFloorShare * full.a);
  if (!limited) return {full - cut, false};
  return {(full.a > cut.a ? full - cut : Jet(0.0)) + kFloorAllowance * cut, true};
}

// The additive-noise slot of a band (npos: none).
std::size_t add_slot(const Layout& L, std::size_t band) {
  const auto it = std::lower_bound(L.add_bands.begin(), L.add_bands.end(), band);
  if (it == L.add_bands.end() || *it != band) return std::string::npos;
  return static_cast<std::size_t>(it - L.add_bands.begin());
}

// Writes one residual: the structural prediction plus the additive noise of its band's slot.
struct ResidualWriter {
  const Layout& L;
  const Values& v;
  const CondSetup& c;
  const Jet& lscale;  // the locked noise's speed scaling
  CondResiduals& out;

  // The locked noise of the slot: in window w, or (w < 0) the cycle's frame-weighted mean of the windows; d: its
  // derivative with respect to each of the slot's log parameters.
  void add_locked(std::size_t slot, int w, Jet& pred, std::vector<double>& d) const {
    const double ref = L.add_ref[slot];
    const std::vector<double>& lx = v.locked[slot];
    if (!L.add_windowed[slot]) {
      const double mv = ref * std::exp(lx[0]);
      pred += lscale * mv;
      d[0] = mv * lscale.a;
    } else if (w >= 0) {
      const double mv = ref * std::exp(lx[static_cast<std::size_t>(w)]);
      pred += lscale * mv;
      d[static_cast<std::size_t>(w)] = mv * lscale.a;
    } else {
      for (std::size_t ww = 0; ww < kW; ++ww) {
        const double mv = ref * std::exp(lx[ww]) * c.frac[ww];
        pred += lscale * mv;
        d[ww] = mv * lscale.a;
      }
    }
  }

  void write(std::size_t ri, double meas, const Clean& structural, std::size_t slot, int w, double weight) const {
    Jet pred = structural.value;
    if (slot != std::string::npos) {
      if (L.on.stationary) {
        const double bg = L.add_ref[slot] * std::exp(v.stat[slot]);
        pred += bg;
        out.dpred_add[ri] = bg;
      }
      if (L.on.locked) {
        std::vector<double> d(v.locked[slot].size(), 0.0);
        add_locked(slot, w, pred, d);
        out.dpred_locked[ri] = std::move(d);
      }
    }
    out.pred[ri] = pred.a;
    out.add_index[ri] = slot;
    out.window[ri] = w;
    out.r[ri] = weight * (kDbPerNeper * std::log(meas) - kDbPerNeper * log(pred));
    if (structural.upper && out.r[ri].a < 0.0) out.r[ri] = Jet(0.0);  // measured below the bound: consistent
  }
};

}  // namespace

void condition_residuals(const Layout& L, const Values& v, const CondSetup& c, bool seed, CondResiduals& out) {
  Jet s[kStruct];
  struct_jets(L, v, s, seed);
  std::vector<Jet> sums, noise;
  structural_sums(L, c, s, sums, noise);
  Jet gain = Jet(1.0);
  if (L.on.speed) gain = pow(Jet(10.0), s[kSSpeedGain] * c.dn_krpm / 10.0);
  const Jet lscale = L.on.locked ? pow(Jet(c.speed_ratio), s[kSLockExp]) : Jet(1.0);
  const std::size_t nres = c.bands.size() + c.wbands.size() * kW;
  out.r.assign(nres, Jet(0.0));
  out.add_index.assign(nres, std::string::npos);
  out.window.assign(nres, -1);
  out.pred.assign(nres, 0.0);
  out.dpred_add.assign(nres, 0.0);
  out.dpred_locked.assign(nres, {});
  std::vector<Jet> mult(c.bands.size()), sub(c.bands.size(), Jet(0.0));
  for (std::size_t i = 0; i < c.bands.size(); ++i) {
    mult[i] = sums[i] / c.f0[i] * gain;
    // The pressure chain's noise: the stationary part of the prediction the noise drove, as mean square (absolute:
    // the small-signal transfer of the block drives it, whatever a nonlinear block does with the loud cycles).
    if (!noise.empty()) sub[i] = noise[i] * gain;
  }
  const ResidualWriter writer{L, v, c, lscale, out};
  for (std::size_t i = 0; i < c.bands.size(); ++i)
    writer.write(i, c.meas[i], minus_noise(c.anchor[i] * mult[i], sub[i], false), add_slot(L, c.bands[i]), -1,
                 c.weight);
  for (std::size_t i = 0; i < c.wbands.size(); ++i) {
    const auto at = std::find(c.bands.begin(), c.bands.end(), c.wbands[i]);
    const std::size_t bi = static_cast<std::size_t>(at - c.bands.begin());
    for (std::size_t w = 0; w < kW; ++w)
      writer.write(c.bands.size() + i * kW + w, c.wmeas[i * kW + w],
                   minus_noise(c.wanchor[i * kW + w] * mult[bi], sub[bi], c.wfloor[i * kW + w] != 0),
                   add_slot(L, c.wbands[i]), static_cast<int>(w), c.wweight);
  }
}

}  // namespace noisemon::model::fit::band_fit_internal
