// Band-spectrum tuning of the block model (thesis ch. 4: the attenuation-curve RMS gap) and the model
// extensions the diagnosis tries on top of it.
//
// Predicted spectra. The block model is re-simulated in the time domain (BlockModel at 40 kHz on the measured
// pressure, through the same 1/3-octave bank as the measurements: segment_band_powers) - the "anchor". Between
// anchors the fit moves on an exact frequency-domain shortcut for everything linear: the predicted band power
// at parameters theta is the anchor's power times
//     F_kb(theta) / F_kb(theta_anchor),   F_kb = sum_f W_b(f) |H_theta(f)|^2 S_k(f)  (times extension factors)
// with S_k the pressure spectrum of condition k and W_b the band's power response. The ratio is exact for a
// linear block in the limit of a stationary spectrum and only has to be right to first order: the fit is
// re-anchored at its result until the step vanishes, so the final figures are always the time-domain
// simulation's. Cubic coefficients (k3, b3) change the waveform, not a transfer function: they are searched
// in an outer 1-D loop (log grid + golden section) with a time-domain anchor per trial value.
//
// The gap of condition k in band b: 10 log10(measured / predicted) = Att_pred - Att_meas (eq. 2.1; the CPL and
// the A-weighting cancel). Cycle-averaged: energy mean over the condition's cycles. The thesis metric: RMS of
// the gap over the scored bands per condition, averaged over conditions.
//
// Which cycles: the fit re-simulates the first `fit_cycles` complete cycles of every training condition
// (documented subset, default 8); held-out figures use every cycle.
//
// One part per file (model/fit/band_fit_*.cpp); band_fit_internal.hpp lists them and holds what they share.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "model/block_params.hpp"
#include "model/fit/band_dataset.hpp"

namespace noisemon::model::fit {

// ------------------------------------------------------------------------------------------ parameters

enum class BlockParam { kK1, kB1, kK3, kB3, kC0, kC1 };
std::string_view param_name(BlockParam p);
double param_value(const BlockParams& params, BlockParam p);
void set_param(BlockParams& params, BlockParam p, double value);
// "k1,b1,c0" -> list; throws std::invalid_argument naming the unknown entry and the valid names.
std::vector<BlockParam> parse_free_params(std::string_view text);
// The default free set: k1, b1, c0, c1, plus k3 / b3 when the start model has them.
std::vector<BlockParam> default_free_params(const BlockParams& start);

// ------------------------------------------------------------------------------------------ extensions

// Model extensions (the diagnosis candidates). Each one is a physical addition to the predicted spectra:
struct ExtensionSet {
  bool second_mode = false;  // a parallel structural resonance: |1 + a R(f)|^2 on the structural path
  bool speed = false;        // structural gain (dB per 1000 rpm) and frequency scaling (per 1000 rpm) with speed
  bool transducer = false;   // a noise floor in the measured pressure: the model is fed S_u - N(f), not S_u
  bool stationary = false;   // stationary additive noise at the microphones, per band (background)
  bool locked = false;       // crank-angle-locked additive noise, per band and crank window, scaling with speed
  bool mic_gain = false;     // microphone calibration offsets (applied to the measurement)
  bool any() const { return second_mode || speed || transducer || stationary || locked || mic_gain; }
};

struct ExtensionParams {
  // The second mode (SecondModeFilter): coupling a = 10^(mode_db/20) - 1 >= 0 at mode_hz with mode_q, radiating at
  // mode_phase_deg against the block's output (0: in phase, +-180: in anti-phase, a dip). Its level change at mode_hz
  // is mode_rise_db().
  double mode_db = 0.0, mode_hz = 2000.0, mode_q = 5.0;
  double mode_phase_deg = 0.0;
  double speed_gain_db_per_krpm = 0.0, speed_shift_per_krpm = 0.0, speed_ref_rpm = 3050.0;
  double transducer_density = 0.0;    // one-sided Pa^2/Hz at 1 kHz
  double transducer_slope = 0.0;      // density ~ (f / 1 kHz)^slope
  std::vector<double> stationary_ms;  // per band, Pa^2
  std::vector<double> locked_ms;      // per band * kCrankWindows: mean square within the window at speed_ref
  double locked_speed_exp = 0.0;      // locked power ~ (n / speed_ref)^exp
  std::vector<double> mic_gain_db;    // per microphone: how many dB it reads high
};

// The second mode's level change at its frequency, 20 log10 |1 + a e^(j phase)|, dB.
double mode_rise_db(const ExtensionParams& e);
// The second mode's phase in radians (held and reported in degrees).
double mode_phase_rad(const ExtensionParams& e);

struct ExtendedModel {
  BlockParams block;
  ExtensionSet on;
  ExtensionParams ext;
};

// ------------------------------------------------------------------------------------------ prediction

// The frequency-domain view of a condition for the shortcut: pressure power per frequency bin and, per band,
// the bins its filter passes with their weights W_b(f) S(f).
struct ConditionSpectrum {
  std::vector<double> f_hz;   // bin frequency
  std::vector<double> df_hz;  // bin width
  std::vector<double> s;      // pressure power in the bin (Pa^2), mean removed
  std::vector<double> floor;  // the judged floor's density in the bin (Pa^2/Hz); empty: none (ConditionInfo)
  struct Tap {
    std::size_t bin;
    double q;
  };  // q = W_b(f) s
  std::vector<std::vector<Tap>> band_taps;
};

// The extension factors of a condition relative to the bare block (per band), given the block at `block` and
// the anchor's block `anchor_block`: predicted = anchor_ms * mult - sub + additive (per cycle and
// window: the same factors).
struct ConditionFactors {
  std::vector<double> mult;     // per band
  std::vector<double> sub;      // per band: stationary part to subtract, mean square (what the pressure chain's
                                // noise alone drove: its judged floor and the transducer candidate's extra)
  std::vector<double> add;      // per band (cycle mean of the additive terms)
  std::vector<double> add_win;  // per band * W (window mean squares of the additive terms)
};
ConditionFactors extension_factors(const BandDataset& data, std::size_t condition, const ConditionSpectrum& spec,
                                   const BlockParams& anchor_block, const ExtendedModel& model);

// Applies the factors to a bare time-domain prediction of the condition's first cycles (and windows), in place.
// Bands (windows) whose prediction the subtracted floor made unobservable, or whose measured pressure is within the
// floor's margin (ConditionInfo::floor_limited_*: the floor may vary along the cycle), are flagged in *upper: their
// value is an upper bound (a measurement below it agrees with the model).
void apply_factors(const ConditionFactors& f, const ConditionData& condition, std::vector<double>& cycle_ms,
                   std::vector<double>* win_ms, std::vector<char>* upper = nullptr,
                   std::vector<char>* upper_win = nullptr);

// Measured microphone-average band mean square of a cycle, corrected by the model's microphone gains.
double measured_ms(const ConditionData& condition, std::size_t cycle, std::size_t band, const ExtendedModel& model);

// ------------------------------------------------------------------------------------------ fitting

struct FitProgress {
  int anchor = 0;       // time-domain re-simulations so far
  int iteration = 0;    // solver iterations in the current anchor
  double rms_db = 0.0;  // current training gap (surrogate)
  std::string note;     // what is happening ("anchor", "b3 = ...", ...)
};

struct FitSetup {
  const BandDataset* data = nullptr;
  std::vector<std::size_t> train;         // condition indices
  std::vector<std::vector<char>> scored;  // per dataset condition, per band: counted (1) or not
  std::vector<BlockParam> free;           // free block parameters (m fixed)
  ExtensionSet extensions;                // free extensions
  std::size_t fit_cycles = 8;             // re-simulated cycles per condition
  int max_anchors = 5;
  double step_tol = 2e-3;      // converged when no log-parameter moves more than this
  bool robust = false;         // soft-L1 loss (scale 3 dB) instead of least squares
  double window_weight = 1.0;  // weight of the crank-window residuals (locked noise only)
  bool evaluate_only = false;  // refit_on_anchor: no solve, figures at the start values
  std::function<void(const FitProgress&)> progress;
};

struct Anchor;

struct FitOutcome {
  ExtendedModel model;
  std::vector<BlockParam> free;
  std::vector<double> sigma;  // 1-sigma uncertainty of each free block parameter (same units), NaN if unknown
  double train_rms_db = 0.0;  // thesis metric over the training conditions, at the final anchor
  double objective = 0.0;     // the weighted sum of squares the fit minimises (at the final anchor)
  int anchors = 0;
  int iterations = 0;
  int parameters = 0;  // fitted parameters (block and extensions)
  bool converged = false;
  std::shared_ptr<const Anchor> anchor;  // the last time-domain anchor (at, or within step_tol of, the result)
};

// Least-squares fit of the free block parameters and extensions on the training conditions (log-scaled
// positive parameters, bounds +-3 decades around the start; cubic coefficients by the outer search).
FitOutcome fit_model(const FitSetup& setup, const ExtendedModel& start);

// One surrogate solve on given anchors (no re-simulation): what the leave-one-condition-out folds use.
struct Anchor {
  BlockParams block;
  std::vector<std::size_t> conditions;
  std::vector<std::vector<double>> cycle_ms;  // per listed condition: [c * bands + b] of the fit cycles
  std::vector<std::vector<double>> win_ms;    // per listed condition (empty without windows)
  std::vector<ConditionSpectrum> spectra;
  std::size_t cycles = 0;
  // Nonlinear blocks: the exact Jacobian of the cycle-averaged band powers, d ln P / d ln theta, per listed
  // condition [b * jac_params.size() + i] (forward differences of re-simulations).
  std::vector<BlockParam> jac_params;
  std::vector<std::vector<double>> jac;
};
Anchor make_anchor(const BandDataset& data, const BlockParams& block, const std::vector<std::size_t>& conditions,
                   std::size_t cycles, bool windows, const std::vector<BlockParam>& jac_params = {});
FitOutcome refit_on_anchor(const FitSetup& setup, const Anchor& anchor, const ExtendedModel& start);

// ------------------------------------------------------------------------------------------ figures

// Gap per cycle-averaged band (dB) of a prediction: gaps[b] = 10 log10(meas / pred) (NaN where not scored).
// pred_ms: per cycle [c * bands + b] (all cycles of the condition), predicted at the model.
std::vector<double> condition_gaps(const ConditionData& condition, const std::vector<double>& pred_ms,
                                   const std::vector<char>& scored, const ExtendedModel& model);
// RMS over the finite entries.
double rms_db(const std::vector<double>& gaps);

// Prediction of every cycle (or of the first `cycles`) of a condition by the model, exactly (time-domain at the
// model's block, its second mode included).
struct ConditionPrediction {
  std::vector<double> cycle_ms;     // [c * bands + b]
  std::vector<double> win_ms;       // [(c * W + w) * bands + b]
  std::vector<char> upper;          // per band: the prediction is an upper bound (see apply_factors); may be empty
  std::vector<char> upper_win;      // per band * W
  std::vector<double> additive_ms;  // per band: the cycle mean of the additive sources' part of cycle_ms (or empty)
};
ConditionPrediction predict_condition(const BandDataset& data, std::size_t condition, const ExtendedModel& model,
                                      bool windows, std::size_t cycles = 0);

}  // namespace noisemon::model::fit
