// What the parts of band fitting (model/fit/band_fit_*.cpp) share; not for use outside model/fit and its tests.
// The method is described in band_fit.hpp. The parts:
//   band_fit_params     block-parameter names and values
//   band_fit_anchor     the time-domain re-simulation (simulate_condition, make_anchor)
//   band_fit_spectrum   the frequency-domain view of a condition (condition_spectrum, band_power_response)
//   band_fit_shortcut   the frequency-domain shortcut: F_b at given structural variables (band_sums)
//   band_fit_residuals  the residuals of one condition in the surrogate (condition_residuals)
//   band_fit_layout     the parameter layout and values of one surrogate problem
//   band_fit_refit      one surrogate solve on an anchor (refit_on_anchor)
//   band_fit            the anchored loop and the start searches (fit_model)
//   band_fit_factors    extension factors applied to time-domain predictions (extension_factors, predict_condition)
//   band_fit_figures    measured levels and gaps
#pragma once

#include <ceres/jet.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

#include "dsp/math_constants.hpp"
#include "model/fit/band_dataset.hpp"
#include "model/fit/band_fit.hpp"
#include "model/fit/pressure_floor.hpp"

namespace noisemon::model::fit::band_fit_internal {

inline constexpr double kDbPerNeper = 10.0 / std::numbers::ln10;  // d(10 log10 x) / d(ln x)
inline constexpr double kAdditiveFloor = 1e-9;  // additive noise bounds, relative to the band's measured power
inline constexpr double kAdditiveCeil = 1e2;
// The pressure chain's noise (its judged floor, and the transducer candidate's extra): the part of a prediction
// the noise drove is subtracted. Where the noise drove more than kFloorShare of it (the pressure is within
// kFloorMarginDb of the noise), the clean prediction is not known well enough to compare with (the floor's
// estimate is good to about 1 dB, 26 %): it becomes an upper bound, the subtracted value plus kFloorAllowance of
// the noise-driven part, and a measurement below it agrees with the model.
inline const double kFloorShare = std::pow(10.0, -kFloorMarginDb / 10.0);  // the share a floor kFloorMarginDb down has
inline constexpr double kFloorAllowance = 0.3;

// ------------------------------------------------------------------------------------------ time and frequency

// Time-domain re-simulation (the anchor) of one condition: block model on the pressure, through the bank.
// Per cycle [c * bands + b] over the first `cycles` cycles of the condition (0: all); windows
// [(c * W + w) * bands + b] when requested. With `mode`, its second mode (mode_db, mode_hz, mode_q) is applied to
// the block's output in the time domain (model/engine/effects' SecondModeFilter) before the bank.
void simulate_condition(const ConditionData& condition, const BlockParams& params, std::size_t cycles,
                        std::vector<double>& cycle_ms, std::vector<double>* win_ms = nullptr,
                        const ExtensionParams* mode = nullptr);

// The frequency-domain view of a condition for the shortcut (ConditionSpectrum) over its first `cycles` cycles.
ConditionSpectrum condition_spectrum(const BandDataset& data, std::size_t condition, std::size_t cycles);
// Power response of band b of the bank (analogue 8th-order Butterworth band-pass with the band's edges; the
// Nyquist-cut band as a high-pass from its lower edge).
double band_power_response(const dsp::ThirdOctaveBand& band, double f_hz);

// ------------------------------------------------------------------------------------------ structural variables

// Structural (shared) variables of the surrogate, as Jet components.
inline constexpr int kStruct = 15;
enum StructIndex : int {
  kSK1 = 0,
  kSB1,
  kSC0,
  kSC1,
  kSModeDb,
  kSModeLogF,
  kSModeLogQ,
  kSSpeedGain,
  kSSpeedShift,
  kSTnLogD,
  kSTnSlope,
  kSLockExp,
  kSK3,
  kSB3,
  kSModePhase
};
using Jet = ceres::Jet<double, kStruct>;

inline constexpr BlockParam kLinearParams[] = {BlockParam::kK1, BlockParam::kB1, BlockParam::kC0, BlockParam::kC1};

int struct_index(BlockParam p);
BlockParam param_of_struct(int idx);
bool is_cubic(BlockParam p);

// Everything the surrogate needs about one training condition.
struct CondSetup {
  std::size_t k = 0;                   // dataset index
  std::vector<std::size_t> bands;      // scored bands
  std::vector<double> meas;            // per scored band: measured (gain-corrected) mean square, fit cycles
  std::vector<double> anchor;          // per scored band: anchor prediction
  std::vector<double> f0;              // per scored band: F at the anchor block, no extensions
  std::vector<double> jac;             // Taylor mode: per scored band * free block params, d ln P / d x
  std::vector<std::size_t> wbands;     // scored window bands (locked noise only)
  std::vector<double> wmeas, wanchor;  // per window band * W
  std::vector<char> wfloor;            // per window band * W: the pressure within its floor's margin
  std::vector<double> frac;            // per window: mean share of the cycle's frames
  double dn_krpm = 0.0;                // (speed - ref) / 1000
  double speed_ratio = 1.0;            // speed / ref
  double weight = 1.0;                 // 1 / sqrt(scored bands)
  double wweight = 0.0;
  const ConditionSpectrum* spec = nullptr;
};

// The parameter layout of one surrogate problem.
struct Layout {
  BlockParams anchor;         // block of the anchor
  BlockParams fixed;          // values of the non-free block parameters (and the start)
  std::vector<int> lin_free;  // struct indices of the free block parameters
  bool taylor = false;        // block part from the anchor's exact Jacobian (nonlinear blocks)
  ExtensionSet on;
  std::vector<std::size_t> add_bands;  // bands with additive-noise parameters
  std::vector<char> add_windowed;      // per add band: W parameters (locked) or 1
  std::vector<double> add_ref;         // per add band: reference mean square
  std::size_t nbands = 0;
};

// Parameter values of one problem (Ceres works on these in place).
struct Values {
  std::vector<double> lin;                  // log(theta / anchor) per free linear parameter
  std::array<double, 4> mode{};             // dB, log(f / 1 kHz), log Q, phase (rad)
  std::array<double, 2> speed{};            // dB per krpm, relative shift per krpm
  std::array<double, 2> tn{};               // log10 density at 1 kHz, slope
  std::array<double, 1> lexp{};             // locked speed exponent
  std::vector<double> stat;                 // per add band: log(B / ref)
  std::vector<std::vector<double>> locked;  // per add band: log(M / ref), W or 1 entries
};

// ------------------------------------------------------------------------------------------ the shortcut

// Structural variables at the given values (derivatives seeded for the free ones).
void struct_jets(const Layout& L, const Values& v, Jet* s, bool seed);

// F_b for the listed bands of a condition at the structural variables (the extensions the layout switches on);
// with noise_out, the part of F_b the pressure chain's noise drove (empty when the condition has no floor and the
// transducer is off). T is double or Jet.
template <typename T>
void band_sums(const Layout& L, const CondSetup& c, const T* s, const std::vector<std::size_t>& bands,
               std::vector<T>& out, std::vector<T>* noise_out = nullptr);
extern template void band_sums<double>(const Layout&, const CondSetup&, const double*, const std::vector<std::size_t>&,
                                       std::vector<double>&, std::vector<double>*);
extern template void band_sums<Jet>(const Layout&, const CondSetup&, const Jet*, const std::vector<std::size_t>&,
                                    std::vector<Jet>&, std::vector<Jet>*);

// ------------------------------------------------------------------------------------------ residuals

// Residuals (and, with Jet, their structural derivatives) of one condition.
struct CondResiduals {
  std::vector<Jet> r;                             // structural part, per residual
  std::vector<std::size_t> add_index;             // per residual: index into Layout::add_bands (or npos)
  std::vector<int> window;                        // per residual: window (or -1 for the cycle value)
  std::vector<double> pred;                       // per residual: predicted mean square
  std::vector<double> dpred_add;                  // per residual: d pred / d (stationary log param)
  std::vector<std::vector<double>> dpred_locked;  // per residual: d pred / d (locked log params of its band)
};

// Per scored band (then per window band and window): weight * (10 log10 measured - 10 log10 predicted), the
// prediction the anchor's times the shortcut's ratio, less the noise-driven part, plus the additive noise.
void condition_residuals(const Layout& L, const Values& v, const CondSetup& c, bool seed, CondResiduals& out);

// ------------------------------------------------------------------------------------------ one surrogate problem

Layout make_layout(const BandDataset& data, const BlockParams& anchor, const BlockParams& start,
                   const std::vector<BlockParam>& free, bool taylor, const ExtensionSet& on,
                   const std::vector<std::size_t>& conds, const std::vector<std::vector<char>>& scored);
// The surrogate's view of listed condition `ai` of the anchor (its scored bands may be none).
CondSetup make_cond_setup(const BandDataset& data, const Anchor& anchor, std::size_t ai, const Layout& L,
                          const FitSetup& setup, const ExtendedModel& model, double ref_rpm);
// Starting values of the parameters from the start model.
Values initial_values(const Layout& L, const ExtendedModel& start, const std::vector<CondSetup>& conds);
ExtendedModel model_from_values(const Layout& L, const Values& v, const ExtendedModel& start);

}  // namespace noisemon::model::fit::band_fit_internal
