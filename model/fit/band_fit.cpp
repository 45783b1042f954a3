#include "model/fit/band_fit.hpp"

#include <ceres/ceres.h>
#include <unsupported/Eigen/FFT>

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <type_traits>

#include "model/block_model.hpp"
#include "model/engine/effects.hpp"
#include "model/fit/pressure_floor.hpp"

namespace noisemon::model {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDbPerNeper = 10.0 / std::numbers::ln10;  // d(10 log10 x) / d(ln x)
constexpr std::size_t kW = kCrankWindows;
constexpr std::size_t kPrimeFrames = 512;   // the block model's modes decay within a millisecond
constexpr double kCompressFromHz = 400.0;   // spectrum bins merged into 1/48-octave bins above this
constexpr double kTapFloor = 1e-8;          // band response below which a bin is left out of a band's sum
constexpr double kAdditiveFloor = 1e-9;     // additive noise bounds, relative to the band's measured power
constexpr double kAdditiveCeil = 1e2;
// The pressure chain's noise (its judged floor, and the transducer candidate's extra): the part of a prediction
// the noise drove is subtracted. Where the noise drove more than kFloorShare of it (the pressure is within
// kFloorMarginDb of the noise), the clean prediction is not known well enough to compare with (the floor's
// estimate is good to about 1 dB, 26 %): it becomes an upper bound, the subtracted value plus kFloorAllowance of
// the noise-driven part, and a measurement below it agrees with the model.
const double kFloorShare = std::pow(10.0, -kFloorMarginDb / 10.0);  // the share a floor kFloorMarginDb down has
constexpr double kFloorAllowance = 0.3;
constexpr double kObservableShare = 0.1;  // a cell's per-cycle value is never taken below this share of the full one
constexpr double kLogBound = 3.0 * std::numbers::ln10;  // +-3 decades around the start
// Start search of a second mode: every scored band centre from kModeSearchLowHz, as a resonance and as an
// absorber of this gain and Q (a few dB, a few bands wide: the fit takes it from there).
constexpr double kModeSearchLowHz = 100.0;
constexpr double kModeSearchDb = 6.0;
constexpr double kModeSearchQ = 4.0;
constexpr std::size_t kModeSearchFits = 4;  // surrogate fits from the best-ranked starts, and as many from the
                                            // bands of the largest training gap

// Structural (shared) variables of the surrogate, as Jet components.
constexpr int kStruct = 14;
enum StructIndex : int { kSK1 = 0, kSB1, kSC0, kSC1, kSModeDb, kSModeLogF, kSModeLogQ, kSSpeedGain, kSSpeedShift,
                         kSTnLogD, kSTnSlope, kSLockExp, kSK3, kSB3 };
using Jet = ceres::Jet<double, kStruct>;

const BlockParam kLinearParams[] = {BlockParam::kK1, BlockParam::kB1, BlockParam::kC0, BlockParam::kC1};

int struct_index(BlockParam p) {
  switch (p) {
    case BlockParam::kK1: return kSK1;
    case BlockParam::kB1: return kSB1;
    case BlockParam::kC0: return kSC0;
    case BlockParam::kC1: return kSC1;
    case BlockParam::kK3: return kSK3;
    case BlockParam::kB3: return kSB3;
  }
  return kSK1;
}
BlockParam param_of_struct(int idx) {
  switch (idx) {
    case kSK1: return BlockParam::kK1;
    case kSB1: return BlockParam::kB1;
    case kSC0: return BlockParam::kC0;
    case kSC1: return BlockParam::kC1;
    case kSK3: return BlockParam::kK3;
    default: return BlockParam::kB3;
  }
}

bool is_cubic(BlockParam p) { return p == BlockParam::kK3 || p == BlockParam::kB3; }

template <typename T>
T block_gain2(const T& w, const T& k1, const T& b1, const T& c0, const T& c1, double m) {
  const T num = c0 * c0 + c1 * c1 * w * w;
  const T re = k1 - m * w * w;
  const T im = b1 * w;
  return num / (re * re + im * im);
}

// |1 + a R(jw)|^2, R = (w2/Q) jw / (w2^2 - w^2 + j w w2/Q): the unit-peak resonance of a second mode.
template <typename T>
T mode_factor2(double w, const T& a, const T& w2, const T& q) {
  const T bw = w2 / q * w;
  const T dre = w2 * w2 - w * w;
  const T den = dre * dre + bw * bw;
  const T rre = bw * bw / den, rim = bw * dre / den;
  const T zr = 1.0 + a * rre, zi = a * rim;
  return zr * zr + zi * zi;
}

// Everything the surrogate needs about one training condition.
struct CondSetup {
  std::size_t k = 0;                       // dataset index
  std::vector<std::size_t> bands;          // scored bands
  std::vector<double> meas;                // per scored band: measured (gain-corrected) mean square, fit cycles
  std::vector<double> anchor;              // per scored band: anchor prediction
  std::vector<double> f0;                  // per scored band: F at the anchor block, no extensions
  std::vector<double> jac;                 // Taylor mode: per scored band * free block params, d ln P / d x
  std::vector<std::size_t> wbands;         // scored window bands (locked noise only)
  std::vector<double> wmeas, wanchor;      // per window band * W
  std::vector<char> wfloor;                // per window band * W: the pressure within its floor's margin
  std::vector<double> frac;                // per window: mean share of the cycle's frames
  double dn_krpm = 0.0;                    // (speed - ref) / 1000
  double speed_ratio = 1.0;                // speed / ref
  double weight = 1.0;                     // 1 / sqrt(scored bands)
  double wweight = 0.0;
  const ConditionSpectrum* spec = nullptr;
};

// The parameter layout of one surrogate problem.
struct Layout {
  BlockParams anchor;                      // block of the anchor
  BlockParams fixed;                       // values of the non-free block parameters (and the start)
  std::vector<int> lin_free;               // struct indices of the free block parameters
  bool taylor = false;                     // block part from the anchor's exact Jacobian (nonlinear blocks)
  ExtensionSet on;
  std::vector<std::size_t> add_bands;      // bands with additive-noise parameters
  std::vector<char> add_windowed;          // per add band: W parameters (locked) or 1
  std::vector<double> add_ref;             // per add band: reference mean square
  std::size_t nbands = 0;
};

// Parameter values of one problem (Ceres works on these in place).
struct Values {
  std::vector<double> lin;                 // log(theta / anchor) per free linear parameter
  std::array<double, 3> mode{};            // dB, log(f / 1 kHz), log Q
  std::array<double, 2> speed{};           // dB per krpm, relative shift per krpm
  std::array<double, 2> tn{};              // log10 density at 1 kHz, slope
  std::array<double, 1> lexp{};            // locked speed exponent
  std::vector<double> stat;                // per add band: log(B / ref)
  std::vector<std::vector<double>> locked; // per add band: log(M / ref), W or 1 entries
};

// Structural variables at the given values (derivatives seeded for the free ones).
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
  s[kSSpeedGain] = Jet(v.speed[0]);
  s[kSSpeedShift] = Jet(v.speed[1]);
  s[kSTnLogD] = Jet(v.tn[0]);
  s[kSTnSlope] = Jet(v.tn[1]);
  s[kSLockExp] = Jet(v.lexp[0]);
  if (seed)
    for (int i = 0; i < kStruct; ++i) s[i].v[i] = 1.0;
}

// F_b for the listed bands of a condition at the structural variables (the extensions the layout switches on).
template <typename T>
void band_sums(const Layout& L, const CondSetup& c, const T* s, const std::vector<std::size_t>& bands, std::vector<T>& out,
               std::vector<T>* noise_out = nullptr) {
  using std::exp;
  using std::pow;
  const ConditionSpectrum& sp = *c.spec;
  const T k1 = L.anchor.k1 * exp(s[kSK1]), b1 = L.anchor.b1 * exp(s[kSB1]);
  const T c0 = L.anchor.c0 * exp(s[kSC0]), c1 = L.anchor.c1 * exp(s[kSC1]);
  T sigma = T(1.0);
  if (L.on.speed) sigma = 1.0 + s[kSSpeedShift] * c.dn_krpm;
  T a = T(0.0), w2 = T(1.0), q = T(1.0);
  if (L.on.second_mode) {
    a = pow(T(10.0), s[kSModeDb] / 20.0) - 1.0;
    w2 = 2.0 * kPi * 1000.0 * exp(s[kSModeLogF]);
    q = exp(s[kSModeLogQ]);
  }
  T density = T(0.0);
  if (L.on.transducer) density = pow(T(10.0), s[kSTnLogD]);
  const std::size_t nbins = sp.f_hz.size();
  const bool with_noise = noise_out && (L.on.transducer || !sp.floor.empty());
  std::vector<T> g(nbins), gn(with_noise ? nbins : 0);
  for (std::size_t j = 0; j < nbins; ++j) {
    const double w = 2.0 * kPi * sp.f_hz[j];
    T gj = block_gain2(T(w) / sigma, k1, b1, c0, c1, L.anchor.m);
    if (L.on.second_mode) gj *= mode_factor2(w, a, w2, q);
    g[j] = gj;
    // The transducer's noise in the bin, as a share of the bin's measured pressure power: what the model
    // predicts from noise alone.
    // The chain's judged floor is known; the transducer candidate fits more on top.
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
  if constexpr (std::is_same_v<T, double>) {
    for (std::size_t i = 0; i < bands.size(); ++i) {
      double sum = 0.0;
      for (const ConditionSpectrum::Tap& t : sp.band_taps[bands[i]]) sum += t.q * g[t.bin];
      out[i] = sum;
    }
  } else {
    // Jets: sum value and derivative parts as plain arrays (the expression templates per tap cost far more).
    constexpr int kDim = kStruct + 1;
    std::vector<std::array<double, kDim>> flat(nbins);
    for (std::size_t j = 0; j < nbins; ++j) {
      flat[j][0] = g[j].a;
      for (int d = 0; d < kStruct; ++d) flat[j][static_cast<std::size_t>(d + 1)] = g[j].v[d];
    }
    for (std::size_t i = 0; i < bands.size(); ++i) {
      std::array<double, kDim> acc{};
      for (const ConditionSpectrum::Tap& t : sp.band_taps[bands[i]]) {
        const std::array<double, kDim>& f = flat[t.bin];
        for (int d = 0; d < kDim; ++d) acc[static_cast<std::size_t>(d)] += t.q * f[static_cast<std::size_t>(d)];
      }
      T sum(acc[0]);
      for (int d = 0; d < kStruct; ++d) sum.v[d] = acc[static_cast<std::size_t>(d + 1)];
      out[i] = sum;
    }
  }
}

// Residuals (and, with Jet, their structural derivatives) of one condition.
struct CondResiduals {
  std::vector<Jet> r;                     // structural part, per residual
  std::vector<std::size_t> add_index;     // per residual: index into Layout::add_bands (or npos)
  std::vector<int> window;                // per residual: window (or -1 for the cycle value)
  std::vector<double> pred;               // per residual: predicted mean square
  std::vector<double> dpred_add;          // per residual: d pred / d (stationary log param)
  std::vector<std::vector<double>> dpred_locked;  // per residual: d pred / d (locked log params of its band)
};

void condition_residuals(const Layout& L, const Values& v, const CondSetup& c, bool seed, CondResiduals& out) {
  Jet s[kStruct];
  struct_jets(L, v, s, seed);
  std::vector<Jet> sums, noise;
  if (L.taylor) {
    // Extensions on the anchor's block; the block's own change from the exact Jacobian.
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
  } else {
    band_sums(L, c, s, c.bands, sums, &noise);
  }
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
  auto add_slot = [&](std::size_t band) {
    const auto it = std::lower_bound(L.add_bands.begin(), L.add_bands.end(), band);
    return (it != L.add_bands.end() && *it == band) ? static_cast<std::size_t>(it - L.add_bands.begin()) : std::string::npos;
  };
  std::vector<Jet> mult(c.bands.size()), sub(c.bands.size(), Jet(0.0));
  for (std::size_t i = 0; i < c.bands.size(); ++i) {
    mult[i] = sums[i] / c.f0[i] * gain;
    // The pressure chain's noise: the stationary part of the prediction the noise drove, as mean square (absolute:
    // the small-signal transfer of the block drives it, whatever a nonlinear block does with the loud cycles).
    if (!noise.empty()) sub[i] = noise[i] * gain;
  }
  // Subtracting the noise-driven part; within the floor's margin the result is an upper bound (censored).
  std::vector<char> censored;
  auto minus = [&](const Jet& full, const Jet& cut, bool at_floor) {
    const bool limited = cut.a > 0.0 && (at_floor || cut.a > kFloorShare * full.a);
    censored.push_back(limited);
    if (!limited) return full - cut;
    return (full.a > cut.a ? full - cut : Jet(0.0)) + kFloorAllowance * cut;
  };
  auto finish = [&](std::size_t ri, double meas, const Jet& structural, std::size_t slot, int w, double weight) {
    const bool upper = !censored.empty() && censored.back();
    Jet pred = structural;
    if (slot != std::string::npos) {
      const double ref = L.add_ref[slot];
      if (L.on.stationary) {
        const double bg = ref * std::exp(v.stat[slot]);
        pred += bg;
        out.dpred_add[ri] = bg;
      }
      if (L.on.locked) {
        const std::vector<double>& lx = v.locked[slot];
        std::vector<double> d(lx.size(), 0.0);
        if (L.add_windowed[slot]) {
          if (w >= 0) {
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
        } else {
          const double mv = ref * std::exp(lx[0]);
          pred += lscale * mv;
          d[0] = mv * lscale.a;
        }
        out.dpred_locked[ri] = std::move(d);
      }
    }
    out.pred[ri] = pred.a;
    out.add_index[ri] = slot;
    out.window[ri] = w;
    out.r[ri] = weight * (kDbPerNeper * std::log(meas) - kDbPerNeper * log(pred));
    if (upper && out.r[ri].a < 0.0) out.r[ri] = Jet(0.0);  // measured below the bound: consistent
  };
  for (std::size_t i = 0; i < c.bands.size(); ++i)
    finish(i, c.meas[i], minus(c.anchor[i] * mult[i], sub[i], false), add_slot(c.bands[i]), -1, c.weight);
  for (std::size_t i = 0; i < c.wbands.size(); ++i) {
    const std::size_t bi = static_cast<std::size_t>(std::find(c.bands.begin(), c.bands.end(), c.wbands[i]) - c.bands.begin());
    for (std::size_t w = 0; w < kW; ++w)
      finish(c.bands.size() + i * kW + w, c.wmeas[i * kW + w], minus(c.wanchor[i * kW + w] * mult[bi], sub[bi], c.wfloor[i * kW + w] != 0),
             add_slot(c.wbands[i]), static_cast<int>(w), c.wweight);
  }
}

// Pointers into Values in the order of the cost function's parameter blocks.
struct BlockRefs {
  std::vector<double*> ptr;
  std::vector<int> size;
  // What each block is: -1 lin, -2 mode, -3 speed, -4 tn, -5 lexp, >= 0: stationary of add slot s (2s) or
  // locked of add slot s (2s + 1).
  std::vector<int> kind;
};

BlockRefs block_refs(const Layout& L, Values& v) {
  BlockRefs b;
  auto add = [&](double* p, int size, int kind) {
    b.ptr.push_back(p);
    b.size.push_back(size);
    b.kind.push_back(kind);
  };
  if (!v.lin.empty()) add(v.lin.data(), static_cast<int>(v.lin.size()), -1);
  if (L.on.second_mode) add(v.mode.data(), 3, -2);
  if (L.on.speed) add(v.speed.data(), 2, -3);
  if (L.on.transducer) add(v.tn.data(), 2, -4);
  if (L.on.locked) add(v.lexp.data(), 1, -5);
  for (std::size_t s = 0; s < L.add_bands.size(); ++s) {
    if (L.on.stationary) add(&v.stat[s], 1, static_cast<int>(2 * s));
    if (L.on.locked) add(v.locked[s].data(), static_cast<int>(v.locked[s].size()), static_cast<int>(2 * s + 1));
  }
  return b;
}

// Struct indices of a block's entries.
std::vector<int> struct_indices(const Layout& L, int kind) {
  switch (kind) {
    case -1: return L.lin_free;
    case -2: return {kSModeDb, kSModeLogF, kSModeLogQ};
    case -3: return {kSSpeedGain, kSSpeedShift};
    case -4: return {kSTnLogD, kSTnSlope};
    case -5: return {kSLockExp};
    default: return {};
  }
}

class ConditionCost final : public ceres::CostFunction {
 public:
  ConditionCost(const Layout& L, const CondSetup& c, const BlockRefs& refs, Values& shadow)
      : L_(L), c_(c), refs_(refs), shadow_(shadow) {
    set_num_residuals(static_cast<int>(c.bands.size() + c.wbands.size() * kW));
    for (int s : refs.size) mutable_parameter_block_sizes()->push_back(s);
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    // Copy the parameter values into a private Values (Ceres may evaluate at trial points).
    Values v = shadow_;
    for (std::size_t i = 0; i < refs_.kind.size(); ++i) {
      const int kind = refs_.kind[i];
      const double* p = parameters[i];
      switch (kind) {
        case -1: std::copy(p, p + refs_.size[i], v.lin.begin()); break;
        case -2: std::copy(p, p + 3, v.mode.begin()); break;
        case -3: std::copy(p, p + 2, v.speed.begin()); break;
        case -4: std::copy(p, p + 2, v.tn.begin()); break;
        case -5: v.lexp[0] = p[0]; break;
        default: {
          const std::size_t slot = static_cast<std::size_t>(kind / 2);
          if (kind % 2 == 0) v.stat[slot] = p[0];
          else std::copy(p, p + refs_.size[i], v.locked[slot].begin());
        }
      }
    }
    CondResiduals out;
    condition_residuals(L_, v, c_, jacobians != nullptr, out);
    const std::size_t nres = out.r.size();
    for (std::size_t r = 0; r < nres; ++r) {
      residuals[r] = out.r[r].a;
      if (!std::isfinite(residuals[r])) return false;
    }
    if (!jacobians) return true;
    for (std::size_t i = 0; i < refs_.kind.size(); ++i) {
      if (!jacobians[i]) continue;
      const int kind = refs_.kind[i];
      const int size = refs_.size[i];
      double* J = jacobians[i];
      std::fill(J, J + nres * static_cast<std::size_t>(size), 0.0);
      if (kind < 0) {
        const std::vector<int> idx = struct_indices(L_, kind);
        for (std::size_t r = 0; r < nres; ++r)
          for (int j = 0; j < size; ++j) J[r * static_cast<std::size_t>(size) + static_cast<std::size_t>(j)] = out.r[r].v[idx[static_cast<std::size_t>(j)]];
        continue;
      }
      const std::size_t slot = static_cast<std::size_t>(kind / 2);
      for (std::size_t r = 0; r < nres; ++r) {
        if (out.add_index[r] != slot) continue;
        const double weight = out.window[r] < 0 ? c_.weight : c_.wweight;
        const double scale = -weight * kDbPerNeper / out.pred[r];
        if (kind % 2 == 0) {
          J[r] = scale * out.dpred_add[r];
        } else {
          const std::vector<double>& d = out.dpred_locked[r];
          for (int j = 0; j < size; ++j) J[r * static_cast<std::size_t>(size) + static_cast<std::size_t>(j)] = scale * d[static_cast<std::size_t>(j)];
        }
      }
    }
    return true;
  }

 private:
  const Layout& L_;
  const CondSetup& c_;
  const BlockRefs& refs_;
  const Values& shadow_;
};

class ProgressCallback final : public ceres::IterationCallback {
 public:
  ProgressCallback(const FitSetup& setup, int anchor, double conditions) : setup_(setup), anchor_(anchor), k_(conditions) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (setup_.progress) {
      FitProgress p;
      p.anchor = anchor_;
      p.iteration = s.iteration;
      p.rms_db = std::sqrt(2.0 * s.cost / std::max(1.0, k_));
      p.note = "solver";
      setup_.progress(p);
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const FitSetup& setup_;
  int anchor_;
  double k_;
};

std::size_t next_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

// Bands whose filter responds fast enough for the crank-angle windows of every listed condition.
double fired_mean_speed(const BandDataset& data, const std::vector<std::size_t>& conds) {
  double s = 0.0;
  int n = 0;
  for (std::size_t k : conds)
    if (!data.conditions[k].info.motored && !data.conditions[k].info.background) {
      s += data.conditions[k].mean_speed_rpm();
      ++n;
    }
  if (n == 0)
    for (std::size_t k : conds) {
      s += data.conditions[k].mean_speed_rpm();
      ++n;
    }
  return n > 0 ? s / n : 3050.0;
}

}  // namespace

// ------------------------------------------------------------------------------------------ parameters

std::string_view param_name(BlockParam p) {
  switch (p) {
    case BlockParam::kK1: return "k1";
    case BlockParam::kB1: return "b1";
    case BlockParam::kK3: return "k3";
    case BlockParam::kB3: return "b3";
    case BlockParam::kC0: return "c0";
    case BlockParam::kC1: return "c1";
  }
  return "?";
}

double param_value(const BlockParams& q, BlockParam p) {
  switch (p) {
    case BlockParam::kK1: return q.k1;
    case BlockParam::kB1: return q.b1;
    case BlockParam::kK3: return q.k3;
    case BlockParam::kB3: return q.b3;
    case BlockParam::kC0: return q.c0;
    case BlockParam::kC1: return q.c1;
  }
  return 0.0;
}

void set_param(BlockParams& q, BlockParam p, double v) {
  switch (p) {
    case BlockParam::kK1: q.k1 = v; break;
    case BlockParam::kB1: q.b1 = v; break;
    case BlockParam::kK3: q.k3 = v; break;
    case BlockParam::kB3: q.b3 = v; break;
    case BlockParam::kC0: q.c0 = v; break;
    case BlockParam::kC1: q.c1 = v; break;
  }
}

std::vector<BlockParam> parse_free_params(std::string_view text) {
  std::vector<BlockParam> out;
  const BlockParam all[] = {BlockParam::kK1, BlockParam::kB1, BlockParam::kK3, BlockParam::kB3, BlockParam::kC0, BlockParam::kC1};
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = text.find(',', pos);
    std::string_view item = text.substr(pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    if (!item.empty()) {
      bool found = false;
      for (BlockParam p : all)
        if (param_name(p) == item) {
          if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
          found = true;
        }
      if (!found)
        throw std::invalid_argument("--free: unknown parameter '" + std::string(item) + "' (valid: k1, b1, k3, b3, c0, c1; m is fixed)");
    }
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  if (out.empty()) throw std::invalid_argument("--free: no parameter given (valid: k1, b1, k3, b3, c0, c1)");
  return out;
}

std::vector<BlockParam> default_free_params(const BlockParams& start) {
  std::vector<BlockParam> out{BlockParam::kK1, BlockParam::kB1, BlockParam::kC0, BlockParam::kC1};
  if (start.k3 > 0) out.push_back(BlockParam::kK3);
  if (start.b3 > 0) out.push_back(BlockParam::kB3);
  return out;
}

// ------------------------------------------------------------------------------------------ prediction

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
      Effects e;
      e.second_mode_db = mode->mode_db;
      e.second_mode_hz = mode->mode_hz;
      e.second_mode_q = mode->mode_q;
      SecondModeFilter(e, kDatasetRateHz).process(y.data(), frames);
    }
    segment_band_powers(seg, y.data(), 1, nc, part, win_ms ? &wpart : nullptr);
    cycle_ms.insert(cycle_ms.end(), part.begin(), part.end());
    if (win_ms) win_ms->insert(win_ms->end(), wpart.begin(), wpart.end());
    done += nc;
  }
}

double band_power_response(const dsp::ThirdOctaveBand& band, double f) {
  if (f <= 0.0) return 0.0;
  if (band.nyquist_cut) return 1.0 / (1.0 + std::pow(band.lower_edge_hz / f, 16));
  const double f0sq = band.lower_edge_hz * band.upper_edge_hz;
  const double x = (f * f - f0sq) / (f * (band.upper_edge_hz - band.lower_edge_hz));
  return 1.0 / (1.0 + std::pow(x * x, 4));
}

namespace {
// A per-band density at each bin: linear in log frequency between the bands' mid frequencies, held beyond them.
std::vector<double> floor_per_bin(const BandDataset& data, const std::vector<double>& per_band, const std::vector<double>& f_hz) {
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
}  // namespace

ConditionSpectrum condition_spectrum(const BandDataset& data, std::size_t k, std::size_t cycles) {
  const ConditionData& cond = data.conditions[k];
  const PreparedSegment& seg = cond.segments.front();
  const std::size_t from = seg.data_start, to = segment_frames(seg, cycles);
  const std::size_t n = to - from;
  const std::size_t nfft = next_pow2(n);
  std::vector<double> buf(nfft, 0.0);
  double mean = 0.0;
  for (std::size_t i = from; i < to; ++i) mean += seg.pressure_pa[i];
  mean /= static_cast<double>(n);
  double wsum2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double w = 0.5 - 0.5 * std::cos(2.0 * kPi * (static_cast<double>(i) + 0.5) / static_cast<double>(n));
    buf[i] = (seg.pressure_pa[from + i] - mean) * w;
    wsum2 += w * w;
  }
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> X;
  fft.fwd(X, buf);
  const double df = kDatasetRateHz / static_cast<double>(nfft);
  ConditionSpectrum sp;
  // One-sided power per FFT bin (Pa^2), merged into 1/48-octave bins above kCompressFromHz.
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
    const double p = 2.0 * std::norm(X[j]) / (static_cast<double>(nfft) * wsum2) * static_cast<double>(nfft) / static_cast<double>(n);
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
  sp.floor = floor_per_bin(data, cond.info.floor_density, sp.f_hz);
  sp.band_taps.resize(data.band_count());
  for (std::size_t b = 0; b < data.band_count(); ++b)
    for (std::size_t j = 0; j < sp.f_hz.size(); ++j) {
      const double w = band_power_response(data.bands[b], sp.f_hz[j]);
      if (w > kTapFloor) sp.band_taps[b].push_back({j, w * sp.s[j]});
    }
  return sp;
}

namespace {

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
  const std::vector<char> wcap = window_capable_bands(data, setup.train);
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
  if (L.on.locked && !anchor.win_ms[ai].empty()) {
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
  c.dn_krpm = (cond.mean_speed_rpm() - ref_rpm) / 1000.0;
  c.speed_ratio = cond.mean_speed_rpm() / ref_rpm;
  c.weight = c.bands.empty() ? 0.0 : 1.0 / std::sqrt(static_cast<double>(c.bands.size()));
  c.wweight = c.wbands.empty() ? 0.0 : std::sqrt(setup.window_weight / static_cast<double>(c.wbands.size() * kW));
  return c;
}

// Starting values of the extension parameters from the start model.
Values initial_values(const Layout& L, const ExtendedModel& start, const std::vector<CondSetup>& conds) {
  Values v;
  for (int idx : L.lin_free) {
    const BlockParam p = param_of_struct(idx);
    v.lin.push_back(std::log(param_value(start.block, p) / param_value(L.anchor, p)));
  }
  const ExtensionParams& e = start.ext;
  v.mode = {e.mode_db, std::log(e.mode_hz / 1000.0), std::log(e.mode_q)};
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
  // Additive noise: from the start, or from the excess the start model leaves (a small share when none).
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
    v.stat[s] = std::log(given_stat > 0 ? std::clamp(given_stat / L.add_ref[s], kAdditiveFloor * 10, kAdditiveCeil / 10) : share);
    const std::size_t nw = L.add_windowed[s] ? kW : 1;
    v.locked[s].assign(nw, std::log(share));
    if (b * kW + kW <= e.locked_ms.size()) {
      for (std::size_t w = 0; w < nw; ++w) {
        double m = 0.0;
        if (nw == kW) m = e.locked_ms[b * kW + w];
        else
          for (std::size_t ww = 0; ww < kW; ++ww) m += e.locked_ms[b * kW + ww] / kW;
        if (m > 0) v.locked[s][w] = std::log(std::clamp(m / L.add_ref[s], kAdditiveFloor * 10, kAdditiveCeil / 10));
      }
    }
  }
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
    for (std::size_t s = 0; s < L.add_bands.size(); ++s) e.stationary_ms[L.add_bands[s]] = L.add_ref[s] * std::exp(v.stat[s]);
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

}  // namespace

double measured_ms(const ConditionData& c, std::size_t cycle, std::size_t b, const ExtendedModel& model) {
  if (!model.on.mic_gain || model.ext.mic_gain_db.size() != c.mics) return c.mic_avg_ms(cycle, b);
  double s = 0.0;
  for (std::size_t m = 0; m < c.mics; ++m) s += c.mic_ms[(cycle * c.mics + m) * c.bands + b] * std::pow(10.0, -model.ext.mic_gain_db[m] / 10.0);
  return s / static_cast<double>(c.mics);
}

ConditionFactors extension_factors(const BandDataset& data, std::size_t k, const ConditionSpectrum& spec,
                                   const BlockParams& anchor_block, const ExtendedModel& model) {
  const std::size_t nb = data.band_count();
  const ConditionData& cond = data.conditions[k];
  Layout L;
  L.anchor = anchor_block;
  L.fixed = model.block;
  L.on = model.on;
  L.nbands = nb;
  Values v;
  const ExtensionParams& e = model.ext;
  v.mode = {e.mode_db, std::log(e.mode_hz / 1000.0), std::log(e.mode_q)};
  v.speed = {e.speed_gain_db_per_krpm, e.speed_shift_per_krpm};
  v.tn = {e.transducer_density > 0 ? std::log10(e.transducer_density) : -300.0, e.transducer_slope};
  v.lexp = {e.locked_speed_exp};
  CondSetup c;
  c.spec = &spec;
  c.dn_krpm = (cond.mean_speed_rpm() - e.speed_ref_rpm) / 1000.0;
  c.speed_ratio = cond.mean_speed_rpm() / e.speed_ref_rpm;
  std::vector<std::size_t> all(nb);
  for (std::size_t b = 0; b < nb; ++b) all[b] = b;
  std::vector<double> with, bare;
  double s[kStruct] = {};
  s[kSK1] = std::log(model.block.k1 / anchor_block.k1);
  s[kSB1] = std::log(model.block.b1 / anchor_block.b1);
  s[kSC0] = std::log(model.block.c0 / anchor_block.c0);
  s[kSC1] = std::log(model.block.c1 / anchor_block.c1);
  s[kSModeDb] = v.mode[0];
  s[kSModeLogF] = v.mode[1];
  s[kSModeLogQ] = v.mode[2];
  s[kSSpeedGain] = v.speed[0];
  s[kSSpeedShift] = v.speed[1];
  s[kSTnLogD] = v.tn[0];
  s[kSTnSlope] = v.tn[1];
  s[kSLockExp] = v.lexp[0];
  std::vector<double> noise;
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
  std::vector<double> frac(kW, 0.0);
  double tot = 0.0;
  for (std::size_t cy = 0; cy < cond.cycle_count(); ++cy)
    for (std::size_t w = 0; w < kW; ++w) {
      frac[w] += cond.win_frames[cy * kW + w];
      tot += cond.win_frames[cy * kW + w];
    }
  for (double& x : frac) x /= tot;
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

FitOutcome refit_on_anchor(const FitSetup& setup, const Anchor& anchor, const ExtendedModel& start) {
  const BandDataset& data = *setup.data;
  const bool taylor = !anchor.jac_params.empty();
  std::vector<BlockParam> lin;
  if (taylor) {
    lin = anchor.jac_params;
  } else {
    for (BlockParam p : setup.free)
      if (!is_cubic(p)) lin.push_back(p);
  }
  ExtendedModel st = start;
  st.on = setup.extensions;
  st.on.mic_gain = start.on.mic_gain;  // fixed gains come with the start model
  st.ext.speed_ref_rpm = fired_mean_speed(data, setup.train);
  Layout L = make_layout(data, anchor.block, st.block, lin, taylor, setup.extensions, setup.train, setup.scored);
  std::vector<CondSetup> conds;
  for (std::size_t i = 0; i < anchor.conditions.size(); ++i) {
    if (std::find(setup.train.begin(), setup.train.end(), anchor.conditions[i]) == setup.train.end()) continue;
    CondSetup c = make_cond_setup(data, anchor, i, L, setup, st, st.ext.speed_ref_rpm);
    if (!c.bands.empty()) conds.push_back(std::move(c));
  }
  if (conds.empty()) throw std::invalid_argument("fit: no training condition has a band to score");
  Values v = initial_values(L, st, conds);
  BlockRefs refs = block_refs(L, v);

  FitOutcome out;
  out.free = setup.free;
  for (int sz : refs.size) out.parameters += sz;
  const bool any_free = !refs.ptr.empty() && !setup.evaluate_only;
  if (any_free) {
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    for (std::size_t i = 0; i < refs.ptr.size(); ++i) problem.AddParameterBlock(refs.ptr[i], refs.size[i]);
    for (const CondSetup& c : conds) {
      ceres::LossFunction* loss = setup.robust ? new ceres::SoftLOneLoss(3.0 * c.weight) : nullptr;
      problem.AddResidualBlock(new ConditionCost(L, c, refs, v), loss, refs.ptr);
    }
    // Bounds.
    for (std::size_t i = 0; i < refs.ptr.size(); ++i) {
      double* p = refs.ptr[i];
      switch (refs.kind[i]) {
        case -1:
          for (int j = 0; j < refs.size[i]; ++j) {
            const double x0 = std::log(param_value(st.block, param_of_struct(L.lin_free[static_cast<std::size_t>(j)])) /
                                       param_value(L.anchor, param_of_struct(L.lin_free[static_cast<std::size_t>(j)])));
            // The Taylor model is trusted within a factor of two around the anchor.
            const bool cubic = is_cubic(param_of_struct(L.lin_free[static_cast<std::size_t>(j)]));
            const double bound = taylor ? std::log(cubic ? 4.0 : 2.0) : kLogBound;
            problem.SetParameterLowerBound(p, j, std::min(x0, 0.0) - bound);
            problem.SetParameterUpperBound(p, j, std::max(x0, 0.0) + bound);
          }
          break;
        case -2:
          problem.SetParameterLowerBound(p, 0, -20.0);
          problem.SetParameterUpperBound(p, 0, 30.0);
          problem.SetParameterLowerBound(p, 1, std::log(0.05));
          problem.SetParameterUpperBound(p, 1, std::log(18.0));
          problem.SetParameterLowerBound(p, 2, std::log(0.5));
          problem.SetParameterUpperBound(p, 2, std::log(50.0));
          break;
        case -3:
          problem.SetParameterLowerBound(p, 0, -40.0);
          problem.SetParameterUpperBound(p, 0, 40.0);
          problem.SetParameterLowerBound(p, 1, -0.3);
          problem.SetParameterUpperBound(p, 1, 0.3);
          break;
        case -4:
          problem.SetParameterLowerBound(p, 0, v.tn[0] - 8.0);
          problem.SetParameterUpperBound(p, 0, v.tn[0] + 4.0);
          problem.SetParameterLowerBound(p, 1, -2.0);
          problem.SetParameterUpperBound(p, 1, 2.0);
          break;
        case -5:
          problem.SetParameterLowerBound(p, 0, -4.0);
          problem.SetParameterUpperBound(p, 0, 8.0);
          break;
        default:
          for (int j = 0; j < refs.size[i]; ++j) {
            problem.SetParameterLowerBound(p, j, std::log(kAdditiveFloor));
            problem.SetParameterUpperBound(p, j, std::log(kAdditiveCeil));
          }
      }
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 60;
    so.function_tolerance = 1e-8;
    so.parameter_tolerance = 1e-8;
    so.logging_type = ceres::SILENT;
    ProgressCallback cb(setup, 0, static_cast<double>(conds.size()));
    if (setup.progress) {
      so.callbacks.push_back(&cb);
      so.update_state_every_iteration = false;
    }
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    out.iterations = static_cast<int>(summary.iterations.size());
    if (getenv("H7DBG")) fprintf(stderr, "solve: %zu conds %d params %zu iterations %d evals\n", conds.size(), out.parameters, summary.iterations.size(), summary.num_residual_evaluations);
    out.converged = summary.termination_type == ceres::CONVERGENCE;
    // Uncertainty of the free linear block parameters: covariance of the log parameters scaled by the
    // residual variance (delta method to the parameters themselves).
    out.sigma.assign(setup.free.size(), std::numeric_limits<double>::quiet_NaN());
    if (!v.lin.empty()) {
      ceres::Covariance::Options co;
      co.algorithm_type = ceres::DENSE_SVD;
      co.null_space_rank = -1;
      ceres::Covariance cov(co);
      std::vector<std::pair<const double*, const double*>> blocks{{v.lin.data(), v.lin.data()}};
      if (cov.Compute(blocks, &problem)) {
        std::vector<double> C(v.lin.size() * v.lin.size());
        cov.GetCovarianceBlock(v.lin.data(), v.lin.data(), C.data());
        const double nres = static_cast<double>(summary.num_residuals);
        const double dof = std::max(1.0, nres - static_cast<double>(summary.num_effective_parameters));
        // Residuals are weighted by 1/sqrt(bands) per condition: the variance of one band's gap is 2 cost
        // * (bands per condition) / dof; the covariance from the weighted problem is scaled to match.
        const double s2 = 2.0 * summary.final_cost / dof;
        ExtendedModel m = model_from_values(L, v, st);
        for (std::size_t i = 0; i < v.lin.size(); ++i) {
          const BlockParam p = param_of_struct(L.lin_free[i]);
          const auto it = std::find(setup.free.begin(), setup.free.end(), p);
          out.sigma[static_cast<std::size_t>(it - setup.free.begin())] =
              param_value(m.block, p) * std::sqrt(std::max(0.0, C[i * v.lin.size() + i] * s2));
        }
      }
    }
  }
  out.model = model_from_values(L, v, st);
  // Training figures at these values (surrogate; exact when the anchor is at the result).
  double sum = 0.0, obj = 0.0;
  for (const CondSetup& c : conds) {
    CondResiduals r;
    condition_residuals(L, v, c, false, r);
    double ms = 0.0;
    for (std::size_t i = 0; i < c.bands.size(); ++i) ms += std::pow(r.r[i].a / c.weight, 2);
    for (const Jet& x : r.r) obj += x.a * x.a;
    sum += std::sqrt(ms / static_cast<double>(c.bands.size()));
  }
  out.train_rms_db = sum / static_cast<double>(conds.size());
  out.objective = obj;
  return out;
}

namespace {

double max_log_step(const BlockParams& a, const BlockParams& b) {
  double m = 0.0;
  for (BlockParam p : kLinearParams) m = std::max(m, std::abs(std::log(param_value(a, p) / param_value(b, p))));
  return m;
}

// The anchored loop: solve on the anchor, re-simulate at the result, accept the step when the exact objective
// does not grow (else halve it in log space). Linear blocks move on the frequency-domain ratio; nonlinear
// blocks (or free cubic coefficients) on the Taylor model of the anchor's exact Jacobian.
FitOutcome fit_anchored(const FitSetup& setup, const ExtendedModel& start, int& anchors) {
  const bool windows = setup.extensions.locked;
  std::vector<BlockParam> jac;
  const bool nonlinear = !start.block.is_linear() ||
                         std::any_of(setup.free.begin(), setup.free.end(), [](BlockParam p) { return is_cubic(p); });
  if (nonlinear)
    for (BlockParam p : setup.free)
      if (param_value(start.block, p) > 0) jac.push_back(p);
  auto anchor_at = [&](const BlockParams& b) {
    ++anchors;
    if (setup.progress) {
      FitProgress p;
      p.anchor = anchors;
      p.note = "re-simulating the training conditions";
      setup.progress(p);
    }
    return make_anchor(*setup.data, b, setup.train, setup.fit_cycles, windows, jac);
  };
  // Exact objective of a model on an anchor at its own block.
  auto exact = [&](const Anchor& an, const ExtendedModel& m) {
    FitSetup ev = setup;
    ev.evaluate_only = true;
    ev.extensions = m.on;
    ev.extensions.mic_gain = false;
    Anchor plain = an;
    plain.jac_params.clear();
    return refit_on_anchor(ev, plain, m);
  };
  ExtendedModel cur = start;
  Anchor anchor = anchor_at(cur.block);
  FitOutcome best = refit_on_anchor(setup, anchor, cur);  // also fits the extensions on the first anchor
  FitOutcome cur_eval = exact(anchor, cur);
  double cur_obj = setup.extensions.any() ? std::numeric_limits<double>::infinity() : cur_eval.objective;
  FitOutcome out = cur_eval;
  out.model = cur;
  out.parameters = best.parameters;
  for (int a = 0; a < setup.max_anchors; ++a) {
    FitOutcome prop = a == 0 ? best : refit_on_anchor(setup, anchor, cur);
    double step = max_log_step(prop.model.block, cur.block);
    if (step < setup.step_tol) {
      // Converged: the extensions are final on this anchor.
      out = prop;
      out.converged = true;
      break;
    }
    bool accepted = false;
    for (int shrink = 0; shrink < 4 && !accepted; ++shrink) {
      Anchor next = anchor_at(prop.model.block);
      FitOutcome ev = exact(next, prop.model);
      if (ev.objective <= cur_obj * (1.0 + 1e-9) || !std::isfinite(cur_obj)) {
        cur = prop.model;
        cur_obj = ev.objective;
        out = ev;
        out.model = cur;
        out.sigma = prop.sigma;
        out.parameters = prop.parameters;
        out.iterations += prop.iterations;
        anchor = std::move(next);
        accepted = true;
      } else {
        // Halve the step of the block parameters; keep the extensions the solve found.
        BlockParams mid = cur.block;
        for (BlockParam p : setup.free) {
          const double x0 = param_value(cur.block, p), x1 = param_value(prop.model.block, p);
          set_param(mid, p, (x0 > 0 && x1 > 0) ? std::sqrt(x0 * x1) : 0.5 * (x0 + x1));
        }
        prop.model.block = mid;
        step = max_log_step(mid, cur.block);
        if (step < setup.step_tol) break;
      }
    }
    if (!accepted) {
      out.converged = true;  // no descent left along the solver's direction
      break;
    }
  }
  out.anchors = anchors;
  out.free = setup.free;
  if (out.sigma.size() != setup.free.size()) out.sigma.assign(setup.free.size(), std::numeric_limits<double>::quiet_NaN());
  out.anchor = std::make_shared<const Anchor>(std::move(anchor));
  return out;
}

double cubic_reference(const BandDataset& data, const FitSetup& setup, const BlockParams& b, BlockParam p) {
  // The size of the cubic coefficient at which the cubic force equals the linear one at the peak velocity or
  // displacement of the training pressure (quasi-static: z = u / k1, z' = u' / k1).
  double umax = 0.0, dumax = 0.0;
  for (std::size_t k : setup.train) {
    const PreparedSegment& s = data.conditions[k].segments.front();
    for (std::size_t i = s.data_start + 1; i < s.pressure_pa.size(); ++i) {
      umax = std::max(umax, std::abs(s.pressure_pa[i]));
      dumax = std::max(dumax, std::abs(s.pressure_pa[i] - s.pressure_pa[i - 1]) * kDatasetRateHz);
    }
  }
  if (p == BlockParam::kK3) {
    const double z = umax / b.k1;
    return z > 0 ? b.k1 / (z * z) : 1e13;
  }
  const double v = dumax / b.k1;
  return v > 0 ? b.b1 / (v * v) : 1e3;
}

}  // namespace

FitOutcome fit_model(const FitSetup& setup, const ExtendedModel& start) {
  int anchors = 0;
  ExtendedModel m = start;
  // A free cubic coefficient that starts at zero needs a scale to start from (the Taylor steps are
  // multiplicative): try a log grid around its natural size, each trial on one re-simulation with the linear
  // parameters moved by the frequency-domain ratio, and start from the best.
  for (BlockParam p : setup.free) {
    if (!is_cubic(p) || param_value(m.block, p) > 0) continue;
    const double ref = cubic_reference(*setup.data, setup, m.block, p);
    FitSetup lin = setup;
    lin.free.clear();
    for (BlockParam q : setup.free)
      if (!is_cubic(q)) lin.free.push_back(q);
    lin.extensions = ExtensionSet{};
    double best_obj = std::numeric_limits<double>::infinity(), best_value = ref;
    for (double g = -2.0; g <= 3.01; g += 0.5) {
      ExtendedModel t = m;
      set_param(t.block, p, ref * std::pow(10.0, g));
      const Anchor an = make_anchor(*setup.data, t.block, setup.train, setup.fit_cycles, false);
      ++anchors;
      const FitOutcome o = refit_on_anchor(lin, an, t);
      if (setup.progress) {
        FitProgress pr;
        pr.anchor = anchors;
        pr.rms_db = o.train_rms_db;
        pr.note = "start search " + std::string(param_name(p)) + " = " + std::to_string(param_value(t.block, p));
        setup.progress(pr);
      }
      if (o.objective < best_obj) {
        best_obj = o.objective;
        best_value = param_value(t.block, p);
      }
    }
    set_param(m.block, p, best_value);
  }
  // A second mode not yet placed: where it sits is a global question (the objective has a local minimum near
  // every band, and none at all in f2 while the mode's gain is 0 dB). On one anchor, rank a resonance and an
  // absorber at every scored 1/3-octave band centre by their objective as they stand (cheap), then run the
  // surrogate fit from the best few (and from the bands where the training gap stands out) and keep the best
  // result as the start.
  if (setup.extensions.second_mode && !m.on.second_mode) {
    const Anchor an = make_anchor(*setup.data, m.block, setup.train, setup.fit_cycles, setup.extensions.locked);
    ++anchors;
    FitSetup rank = setup;
    rank.evaluate_only = true;
    std::vector<std::pair<double, ExtensionParams>> starts;
    for (const dsp::ThirdOctaveBand& band : setup.data->bands) {
      if (band.nyquist_cut || band.nominal_hz < kModeSearchLowHz) continue;
      for (double gain_db : {kModeSearchDb, -kModeSearchDb}) {
        ExtendedModel t = m;
        t.ext.mode_hz = band.exact_mid_hz;
        t.ext.mode_q = kModeSearchQ;
        t.ext.mode_db = gain_db;
        starts.emplace_back(refit_on_anchor(rank, an, t).objective, t.ext);
      }
    }
    std::sort(starts.begin(), starts.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    starts.resize(std::min<std::size_t>(kModeSearchFits, starts.size()));
    // The ranking holds the block where the baseline left it, which has already bent towards the mode; the
    // bands where the training gap (measured over predicted, cycle-averaged) stands out most are started from too.
    const BandDataset& data = *setup.data;
    const std::size_t nb = data.band_count();
    std::vector<double> gap(nb, 0.0);
    std::vector<int> count(nb, 0);
    for (std::size_t i = 0; i < an.conditions.size(); ++i) {
      const std::size_t k = an.conditions[i];
      const ConditionData& cond = data.conditions[k];
      const std::size_t nc = an.cycle_ms[i].size() / nb;
      for (std::size_t b = 0; b < nb; ++b) {
        if (!setup.scored[k][b]) continue;
        double meas = 0.0, pred = 0.0;
        for (std::size_t c = 0; c < nc; ++c) {
          meas += measured_ms(cond, c, b, m);
          pred += an.cycle_ms[i][c * nb + b];
        }
        if (meas > 0 && pred > 0) {
          gap[b] += 10.0 * std::log10(meas / pred);
          ++count[b];
        }
      }
    }
    std::vector<std::size_t> by_gap;
    for (std::size_t b = 0; b < nb; ++b)
      if (count[b] > 0 && data.bands[b].nominal_hz >= kModeSearchLowHz) {
        gap[b] /= count[b];
        by_gap.push_back(b);
      }
    std::sort(by_gap.begin(), by_gap.end(), [&](std::size_t a, std::size_t b) { return std::abs(gap[a]) > std::abs(gap[b]); });
    for (std::size_t i = 0; i < std::min<std::size_t>(kModeSearchFits, by_gap.size()); ++i) {
      ExtensionParams e = m.ext;
      e.mode_hz = data.bands[by_gap[i]].exact_mid_hz;
      e.mode_q = kModeSearchQ;
      e.mode_db = std::copysign(kModeSearchDb, gap[by_gap[i]]);
      starts.emplace_back(0.0, e);
    }
    double best_obj = std::numeric_limits<double>::infinity();
    ExtensionParams best_ext = m.ext;
    for (std::size_t i = 0; i < starts.size(); ++i) {
      ExtendedModel t = m;
      t.ext = starts[i].second;
      const FitOutcome o = refit_on_anchor(setup, an, t);
      if (o.objective < best_obj) {
        best_obj = o.objective;
        best_ext = o.model.ext;
      }
    }
    if (setup.progress) {
      FitProgress pr;
      pr.anchor = anchors;
      pr.note = "second mode starts near " + std::to_string(static_cast<int>(best_ext.mode_hz)) + " Hz";
      setup.progress(pr);
    }
    m.ext.mode_hz = best_ext.mode_hz;
    m.ext.mode_q = best_ext.mode_q;
    m.ext.mode_db = best_ext.mode_db;
  }
  FitOutcome out = fit_anchored(setup, m, anchors);
  out.anchors = anchors;
  return out;
}

// ------------------------------------------------------------------------------------------ figures

std::vector<double> condition_gaps(const ConditionData& cond, const std::vector<double>& pred_ms,
                                   const std::vector<char>& scored, const ExtendedModel& model) {
  const std::size_t nb = cond.bands, nc = cond.cycle_count();
  std::vector<double> gaps(nb, std::numeric_limits<double>::quiet_NaN());
  for (std::size_t b = 0; b < nb; ++b) {
    if (!scored[b]) continue;
    double m = 0.0, p = 0.0;
    for (std::size_t c = 0; c < nc; ++c) {
      m += measured_ms(cond, c, b, model);
      p += pred_ms[c * nb + b];
    }
    if (m > 0 && p > 0) gaps[b] = 10.0 * std::log10(m / p);
  }
  return gaps;
}

double rms_db(const std::vector<double>& gaps) {
  double s = 0.0;
  int n = 0;
  for (double g : gaps)
    if (std::isfinite(g)) {
      s += g * g;
      ++n;
    }
  return n > 0 ? std::sqrt(s / n) : std::numeric_limits<double>::quiet_NaN();
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
        for (std::size_t w = 0; w < kW; ++w) wmean[b * kW + w] += (*win_ms)[(c * kW + w) * nb + b] / static_cast<double>(nc);
    }
  // Censoring is decided on the condition's means (see kFloorShare).
  std::vector<char> cb(nb, 0), cw(nb * kW, 0);
  for (std::size_t b = 0; b < nb; ++b) {
    if (f.sub[b] == 0.0) continue;
    const auto at_floor = [&](const std::vector<char>& flags, std::size_t i) { return i < flags.size() && flags[i]; };
    cb[b] = f.sub[b] > kFloorShare * mean[b] * f.mult[b] || at_floor(cond.info.floor_limited_band, b);
    if (windows)
      for (std::size_t w = 0; w < kW; ++w)
        cw[b * kW + w] =
            f.sub[b] > kFloorShare * wmean[b * kW + w] * f.mult[b] || at_floor(cond.info.floor_limited_window, b * kW + w);
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
  apply_factors(extension_factors(data, k, spec, model.block, rest), data.conditions[k], p.cycle_ms,
                windows ? &p.win_ms : nullptr, &p.upper, &p.upper_win);
  return p;
}

}  // namespace noisemon::model
