// The frequency-domain shortcut: F_b = sum_f W_b(f) |H(f)|^2 S(f) (times the extensions' factors) at given
// structural variables, in plain doubles or in Jets (with the derivatives the surrogate's solver needs).
#include <array>
#include <cmath>

#include "model/fit/band_fit_internal.hpp"

namespace noisemon::model::fit::band_fit_internal {
namespace {

template <typename T>
T block_gain2(const T& w, const T& k1, const T& b1, const T& c0, const T& c1, double m) {
  const T num = c0 * c0 + c1 * c1 * w * w;
  const T re = k1 - m * w * w;
  const T im = b1 * w;
  return num / (re * re + im * im);
}

// |1 + a (cos(phi) R - sin(phi) D)|^2 (SecondModeFilter): R = (w2/Q) jw / (w2^2 - w^2 + j w w2/Q), the unit-peak
// resonance of a second mode, and D = (w2^2/Q) / (w2^2 - w^2 + j w w2/Q), its displacement-like partner (-j at w2).
template <typename T>
T mode_factor2(double w, const T& a, const T& w2, const T& q, const T& phi) {
  using std::cos;
  using std::sin;
  const T bw = w2 / q * w;
  const T dre = w2 * w2 - w * w;
  const T den = dre * dre + bw * bw;
  const T rre = bw * bw / den, rim = bw * dre / den;
  const T dscale = w2 * w2 / q / den;
  const T dr = dscale * dre, di = -dscale * bw;
  const T c = cos(phi), s = sin(phi);
  const T zr = 1.0 + a * (c * rre - s * dr), zi = a * (c * rim - s * di);
  return zr * zr + zi * zi;
}

// sum over each listed band's taps of q * g[bin].
void sum_taps(const ConditionSpectrum& sp, const std::vector<std::size_t>& bands, const std::vector<double>& g,
              std::vector<double>& out) {
  for (std::size_t i = 0; i < bands.size(); ++i) {
    double sum = 0.0;
    for (const ConditionSpectrum::Tap& t : sp.band_taps[bands[i]]) sum += t.q * g[t.bin];
    out[i] = sum;
  }
}

void sum_taps(const ConditionSpectrum& sp, const std::vector<std::size_t>& bands, const std::vector<Jet>& g,
              std::vector<Jet>& out) {
  // Jets: sum value and derivative parts as plain arrays (the expression templates per tap cost far more).
  constexpr int kDim = kStruct + 1;
  const std::size_t nbins = g.size();
  std::vector<std::array<double, kDim>> flat(nbins);
  for (std::size_t j = 0; j < nbins; ++j) {
    flat[j][0] = g[j].a;
    for (int d = 0; d < kStruct; ++d) flat[j][static_cast<std::size_t>(d) + 1] = g[j].v[d];
  }
  for (std::size_t i = 0; i < bands.size(); ++i) {
    std::array<double, kDim> acc{};
    for (const ConditionSpectrum::Tap& t : sp.band_taps[bands[i]]) {
      const std::array<double, kDim>& f = flat[t.bin];
      for (int d = 0; d < kDim; ++d) acc[static_cast<std::size_t>(d)] += t.q * f[static_cast<std::size_t>(d)];
    }
    Jet sum(acc[0]);
    for (int d = 0; d < kStruct; ++d) sum.v[d] = acc[static_cast<std::size_t>(d) + 1];
    out[i] = sum;
  }
}

}  // namespace

void struct_jets(const Layout& L, const Values& v, Jet* s, bool seed) {
  for (int i = 0; i < kStruct; ++i) s[i] = Jet(0.0);
  s[kSK1] = Jet(std::log(L.fixed.k1 / L.anchor.k1));
  s[kSB1] = Jet(std::log(L.fixed.b1 / L.anchor.b1));
  s[kSC0] = Jet(std::log(L.fixed.c0 / L.anchor.c0));
  s[kSC1] = Jet(std::log(L.fixed.c1 / L.anchor.c1));
  s[kSK3] = Jet(L.anchor.k3 > 0 && L.fixed.k3 > 0 ? std::log(L.fixed.k3 / L.anchor.k3) : 0.0);
  s[kSB3] = Jet(L.anchor.b3 > 0 && L.fixed.b3 > 0 ? std::log(L.fixed.b3 / L.anchor.b3) : 0.0);
  for (std::size_t i = 0; i < L.lin_free.size(); ++i) s[L.lin_free[i]] = Jet(v.lin[i]);
  s[kSModeDb] = Jet(v.mode[0]);
  s[kSModeLogF] = Jet(v.mode[1]);
  s[kSModeLogQ] = Jet(v.mode[2]);
  s[kSModePhase] = Jet(v.mode[3]);
  s[kSSpeedGain] = Jet(v.speed[0]);
  s[kSSpeedShift] = Jet(v.speed[1]);
  s[kSTnLogD] = Jet(v.tn[0]);
  s[kSTnSlope] = Jet(v.tn[1]);
  s[kSLockExp] = Jet(v.lexp[0]);
  if (seed)
    for (int i = 0; i < kStruct; ++i) s[i].v[i] = 1.0;
}

template <typename T>
void band_sums(const Layout& L, const CondSetup& c, const T* s, const std::vector<std::size_t>& bands,
               std::vector<T>& out, std::vector<T>* noise_out) {
  using std::exp;
  using std::pow;
  const ConditionSpectrum& sp = *c.spec;
  const T k1 = L.anchor.k1 * exp(s[kSK1]), b1 = L.anchor.b1 * exp(s[kSB1]);
  const T c0 = L.anchor.c0 * exp(s[kSC0]), c1 = L.anchor.c1 * exp(s[kSC1]);
  T sigma = T(1.0);
  if (L.on.speed) sigma = 1.0 + s[kSSpeedShift] * c.dn_krpm;
  T a = T(0.0), w2 = T(1.0), q = T(1.0), phi = T(0.0);
  if (L.on.second_mode) {
    a = pow(T(10.0), s[kSModeDb] / 20.0) - 1.0;
    w2 = 2.0 * kPi * 1000.0 * exp(s[kSModeLogF]);
    q = exp(s[kSModeLogQ]);
    phi = s[kSModePhase];
  }
  T density = T(0.0);
  if (L.on.transducer) density = pow(T(10.0), s[kSTnLogD]);
  const std::size_t nbins = sp.f_hz.size();
  const bool with_noise = noise_out && (L.on.transducer || !sp.floor.empty());
  std::vector<T> g(nbins), gn(with_noise ? nbins : 0);
  for (std::size_t j = 0; j < nbins; ++j) {
    const double w = 2.0 * kPi * sp.f_hz[j];
    T gj = block_gain2(T(w) / sigma, k1, b1, c0, c1, L.anchor.m);
    if (L.on.second_mode) gj *= mode_factor2(w, a, w2, q, phi);
    g[j] = gj;
    // The noise in the bin, as a share of the bin's measured pressure power: what the model predicts from noise
    // alone. The chain's judged floor is known; the transducer candidate fits more on top.
    if (with_noise) {
      T d = L.on.transducer ? density * pow(T(sp.f_hz[j] / 1000.0), s[kSTnSlope]) : T(0.0);
      if (!sp.floor.empty()) d += sp.floor[j];
      gn[j] = gj * (d * sp.df_hz[j] / sp.s[j]);
    }
  }
  if (with_noise) {
    noise_out->resize(bands.size());
    for (std::size_t i = 0; i < bands.size(); ++i) {
      T sum = T(0.0);
      for (const ConditionSpectrum::Tap& t : sp.band_taps[bands[i]]) sum += t.q * gn[t.bin];
      (*noise_out)[i] = sum;
    }
  }
  out.resize(bands.size());
  sum_taps(sp, bands, g, out);
}

template void band_sums<double>(const Layout&, const CondSetup&, const double*, const std::vector<std::size_t>&,
                                std::vector<double>&, std::vector<double>*);
template void band_sums<Jet>(const Layout&, const CondSetup&, const Jet*, const std::vector<std::size_t>&,
                             std::vector<Jet>&, std::vector<Jet>*);

}  // namespace noisemon::model::fit::band_fit_internal
