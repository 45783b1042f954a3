// The sim-to-real gap diagnosis: where the tuned block model and the measurements disagree, which unmodelled
// effect of the list (docs/diagnosis.md) explains it, and how much of the gap that effect closes on conditions it was
// not fitted to.
//
// Roles of the conditions. Fired conditions are scored. Motored runs are reference runs: they carry the
// combustion-independent noise and take part in every fit, never in a score. Background runs (engine off)
// give the irreducible floor: a band less than 6 dB above it (the ISO 3744 limit for a background correction)
// is not scored. Bands cut by the Nyquist frequency and low bands without a harmonic of the cycle frequency are
// not scored either (reported, not hidden).
//
// Baseline: the start model tuned (band_fit, default free k1, b1, c0, c1) on the training conditions, on the
// bands where combustion noise dominates (at least 6 dB above the combustion-independent excess of the motored
// runs: the block must not bend to fit noise it cannot make; the excess judged beyond the start model, then again
// beyond the tuned block, and the baseline tuned once more when the bands changed). Candidates: the baseline plus
// one extension, every parameter refitted on ALL scored bands of the training conditions, fired and motored:
//   cubic_damping      free b3                         cubic_stiffness   free k3
//   second_mode        parallel resonance (dB, f2, Q)  speed_dependence  gain and frequency scaling per krpm
//   mechanical_noise   additive, per band and crank window, scaling with a power of speed
//   background_noise   additive, per band, stationary  transducer_noise  pressure-sensor floor (density, slope)
//   mic_gain           microphone calibration offsets (the channels that stand out of the array's spread)
// Held-out: leave-one-condition-out over the fired conditions (each fold refits on the others: a surrogate
// solve on the all-training anchor, then an exact re-simulation of the held-out condition), or the given
// train / hold-out split. Never a split of neighbouring cycles. Beside it, when some operating speed holds several
// fired conditions, leave-one-group-out by speed (the thesis's idle and full-load groups), reported beside it: how
// well each model carries from some operating points to another. Not a gate: with two groups it mostly measures
// the block's own extrapolation (the thesis's linear model, tuned at idle, misses full load by 5 dB), which a true
// additive source refitted beside it can make a little worse.
//
// The held-out gap (what candidates are ranked by) has three parts, each zero for a model that explains the
// data: (1) the thesis gap: per band, cycle-averaged, microphone-averaged; (2) the microphone calibration
// residual: per microphone, its offset from the array (mean over bands) beyond the array's own spread
// (robust 3-sigma soft threshold), root-sum-square over microphones; (3) the crank-angle-window gap: per
// fast band and 90-degree window, after the stationary floor the model leaves on the training data (so it
// measures crank-angle locking, not stationary noise). Gap = sqrt(MS1 + RSS2^2 + MS3), averaged over held-out
// conditions in the squares. The thesis metric (part 1 alone, RMS per condition averaged over conditions) is
// reported beside it.
//
// Significance: bootstrap over cycles (within each held-out condition, the same resampled cycles for every
// model): a candidate is significant when its gap is below the baseline's in at least 95 % of the replicates
// and the improvement is at least `min_improvement_db`. Ranking: held-out gap, best first; a simpler candidate
// (fewer fitted parameters) ranks first when the better one does not beat it in 95 % of the replicates by at least
// `min_improvement_db`, or when its information criterion is not the lower (a 90-level spectrum must not beat a
// 4-parameter mode by fitting the noise); a candidate that makes the held-out thesis metric worse (by more than
// 0.05 dB), or whose criterion is not below the baseline's, is never significant.
// Verdict: `none` when the baseline's held-out gap is within `tolerance_db` (or not above its bootstrap noise);
// otherwise the best significant candidate when it (alone or with a second one) closes at least
// `min_closed_fraction` of the gap or leaves no more than `tolerance_db`, else `unexplained`.
//
// The stages, one file each, are declared in stages.hpp (internal to model/diagnosis).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "model/fit/band_dataset.hpp"
#include "model/fit/band_fit.hpp"

namespace noisemon::model::diagnosis {

// The candidate effects, the listed names in docs/diagnosis.md's order.
const std::vector<std::string>& candidate_effects();

struct DiagnosisOptions {
  std::vector<std::string> train;       // condition patterns for training (empty: every fired condition not held out)
  std::vector<std::string> holdout;     // condition patterns held out (empty: leave-one-condition-out)
  std::vector<fit::BlockParam> free;    // baseline free parameters (empty: default_free_params)
  std::vector<std::string> candidates;  // subset of candidate_effects() (empty: all)
  std::size_t fit_cycles = 8;
  int bootstrap = 200;
  std::uint64_t seed = 1;
  double tolerance_db = 0.5;  // baseline agrees within this held-out gap: `none`
  double min_improvement_db = 0.1;
  double min_closed_fraction = 0.5;
  double floor_margin_db = 6.0;  // ISO 3744: a band must be this far above a floor to be trusted
  std::function<void(const std::string&)> progress;
};

// A condition pattern matches a name equal to it, starting with it followed by '_' (so "idle" matches
// "idle_mi12"), or as a glob with '*'.
bool condition_matches(const std::string& pattern, const std::string& name);

struct ModelScore {
  std::string name;  // "baseline" or the effect (or "a+b" for a combination)
  std::vector<std::string> effects;
  fit::ExtendedModel model;                     // fitted on all training conditions
  std::vector<fit::ExtendedModel> fold_models;  // per held-out condition
  int parameters = 0;                           // fitted parameters (complexity): every free level counted
  // Parsimony: the held-out cells scored (band cells, crank-window cells, microphones, over the held-out
  // conditions) and a Bayesian information criterion on them, n ln(gap^2) + parameters ln(n) (gap.cpp): the
  // held-out gap already costs a model whatever it fitted to noise; this also charges it for every free level.
  int heldout_cells = 0;
  double information_criterion = 0.0;
  bool pays_for_parameters = true;     // its criterion is below the baseline's: else never significant
  double train_rms_db = 0.0;           // thesis metric over the training fired conditions
  double heldout_thesis_rms_db = 0.0;  // thesis metric over the held-out conditions
  double heldout_gap_db = 0.0;         // the ranking gap (see the top of the file)
  double part_band_ms = 0.0, part_mic = 0.0, part_window_ms = 0.0;
  // Leave-one-group-out (conditions grouped by operating speed, when some speed has several): the held-out gap
  // with each group's fired conditions predicted by a model fitted without any of them (NaN: no groups).
  double heldout_group_gap_db = std::numeric_limits<double>::quiet_NaN();
  bool group_worse = false;  // its group gap is worse than the baseline's by more than 0.05 dB (reported)
  // Per held-out condition (the order of DiagnosisResult::heldout):
  std::vector<std::vector<double>> gaps;         // per band, dB (NaN where not scored)
  std::vector<std::vector<double>> att_pred;     // predicted attenuation CPL - SPL_A per band, dB
  std::vector<std::vector<double>> mic_resid;    // per microphone, calibration residual after the model, dB
  std::vector<std::vector<double>> window_gaps;  // per window: mean gap over the fast bands, dB
  std::vector<std::vector<double>> cell_gaps;    // per window * bands + band: gap, dB (NaN where not scored)
  // Bootstrap against the baseline.
  double improvement_db = 0.0;      // baseline gap - this gap
  double improvement_p05_db = 0.0;  // 5th percentile of the replicates
  double win_fraction = 0.0;        // share of replicates where this gap < baseline's
  bool significant = false;         // alone, against the baseline
  bool significant_on_top = false;  // the verdict's partner: significant on top of the verdict's effect
  bool thesis_worse = false;        // its held-out thesis metric is worse than the baseline's: never significant
  // The motored runs' law (additive candidates, motored_law.cpp): the source alone never louder than all the sound
  // the motored runs measure. The largest excess over the measurement beyond 3 standard errors, dB, and where.
  bool motored_law_checked = false;
  double motored_overshoot_db = std::numeric_limits<double>::quiet_NaN();
  std::string motored_overshoot_where;
  // The pressure-driven candidates' law (motored_law.cpp): the motored runs predicted no worse than by the baseline.
  // How much worse (RMS over the bands, beyond 3 standard errors), dB, and in which run.
  bool pressure_law_checked = false;
  double motored_worse_db = std::numeric_limits<double>::quiet_NaN();
  std::string motored_worse_where;
  bool refuted = false;  // either law broken beyond the margin: never significant
  // How much of each part of the baseline's gap it closes, dB (baseline part minus this part; negative: worse).
  double closes_band_db = 0.0, closes_mic_db = 0.0, closes_window_db = 0.0;
  double gap_closed_fraction = 0.0;    // 1 - gap / baseline gap
  std::vector<double> replicate_gaps;  // for the pairwise tie-break
};

struct Where {
  std::vector<double> band_hz;
  std::vector<std::string> conditions;             // every condition, dataset order
  std::vector<std::string> roles;                  // "train", "heldout", "train+heldout" (LOCO), "reference", "floor"
  std::vector<std::vector<char>> scored;           // per condition, per band
  std::vector<std::vector<char>> floor_limited;    // per condition, per band: at a floor (pressure chain or the
                                                   // background runs), never fitted or scored
  std::vector<std::vector<char>> noise_dominated;  // per condition, per band: within the margin of the motored
                                                   // runs' combustion-independent excess (scored, not tuned on)
  std::vector<std::string> band_notes;             // per band: "nyquist_cut", "line_free", "" ...
  std::vector<double> floor_db;                    // per band: combustion-independent level (motored excess), dB
  std::vector<double> background_db;               // per band: background-run level (NaN without one)
  // The measurement chains' floors (model/fit/pressure_floor.hpp), per condition (dataset order):
  std::vector<std::string> pressure_floor_judged_by;      // "stated", "estimated" or "none"
  std::vector<double> pressure_floor_stated_bar;          // rms per encoder sample (NaN: none stated)
  std::vector<double> pressure_floor_estimated_bar;       // the estimate, likewise (NaN without the encoder rate)
  std::vector<double> pressure_floor_estimated_grid_bar;  // the estimate as rms over its extent on the 40 kHz grid
  std::vector<std::vector<double>> pressure_floor_db;     // per band: the judged floor's level, dB re 20 uPa (as CPL)
  std::vector<int> floor_limited_bands;                   // per condition: band cells at a floor
  std::vector<int> floor_limited_windows;                 // per condition: crank-window cells at the pressure floor
  std::vector<double> mic_floor_db;                       // per band: the microphones' floor, dB re 20 uPa
  std::string mic_floor_source;                           // "background runs" or "quiet crank windows"
  std::vector<std::string> floor_summary;                 // one line per group of conditions
  // Baseline held-out gap per condition (rows: held-out conditions) and band, dB.
  std::vector<std::vector<double>> gap;
  std::vector<double> gap_per_band_rms;                 // over held-out conditions
  std::vector<double> gap_per_condition_rms;            // thesis metric per held-out condition
  std::vector<double> cpl_overall_db;                   // per held-out condition: overall CPL (input level)
  std::vector<double> mean_gap_db;                      // per held-out condition: mean gap over scored bands
  double amplitude_slope_db_per_db = 0.0;               // mean gap vs CPL across held-out conditions
  double cycle_amplitude_slope_db_per_db = 0.0;         // per-cycle gap vs per-cycle CPL, within conditions (pooled)
  double speed_slope_db_per_krpm = 0.0;                 // mean gap vs speed across held-out conditions
  double soi_slope_db_per_deg = 0.0;                    // mean gap vs injection timing (deg BTDC) across them
  double load_slope_db_per_nm = 0.0;                    // mean gap vs load across them (NaN: all at one value)
  std::vector<std::string> mics;                        // "mic1".. (Table 3.1 numbering)
  std::vector<double> mic_offset_db;                    // per microphone: mean offset from the array, over conditions
  std::vector<double> mic_gap_rms_db;                   // per microphone: thesis metric of its own curve
  std::vector<double> window_gap_db;                    // per crank window: mean baseline gap over fast bands
  std::vector<std::vector<double>> window_band_gap_db;  // [window][band]: mean baseline gap over conditions
  std::vector<double> window_start_deg;
  std::vector<double> coherent_fraction;  // per band, mean over fired conditions
  std::vector<double> fluct_coherence;
  std::vector<double> periodic_share;
  // Measured and predicted attenuation (CPL - SPL_A, dB), per held-out condition and band.
  std::vector<std::vector<double>> att_meas;
  std::vector<std::vector<double>> att_base;
  std::vector<std::vector<double>> cpl_db;
};

// What the verdict leaves: the selected model's held-out gap (the baseline's for `none` and `unexplained`), where it
// lies and how its mean (measured over predicted, per held-out condition) scales with speed, load and input level.
struct RemainingGap {
  std::string model;    // "baseline", the effect, or "a+b"
  double gap_db = 0.0;  // its held-out gap
  std::string part;     // the largest part of it: "bands", "microphones" or "crank windows"
  double largest_band_hz = std::numeric_limits<double>::quiet_NaN();  // nominal centre of the band with most
  double largest_band_db = std::numeric_limits<double>::quiet_NaN();  // its RMS over the held-out conditions
  double from_hz = std::numeric_limits<double>::quiet_NaN();          // the contiguous bands around it at >= half
  double to_hz = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> mean_gap_db;                                            // per held-out condition
  double speed_slope_db_per_krpm = std::numeric_limits<double>::quiet_NaN();  // NaN: fewer than two speeds
  double load_slope_db_per_nm = std::numeric_limits<double>::quiet_NaN();
  double level_slope_db_per_db = std::numeric_limits<double>::quiet_NaN();  // against the overall CPL
  std::string summary;                                                      // one line
};

struct Verdict {
  std::string effect;                  // candidate name, "none" or "unexplained"
  std::vector<std::string> also;       // further significant effects in the selected set
  double heldout_rms_before_db = 0.0;  // held-out gap of the baseline
  double heldout_rms_after_db = 0.0;   // of the selected set (the baseline when none)
  double heldout_thesis_before_db = 0.0;
  double heldout_thesis_after_db = 0.0;
  double gap_closed_fraction = 0.0;
  double noise_db = 0.0;               // bootstrap spread of the baseline's gap
  std::vector<double> band_before_db;  // per band: RMS over held-out conditions
  std::vector<double> band_after_db;
  std::string explanation;  // one or two sentences
  // When `none` by the tolerance alone (the gap above its noise): the best significant candidate, the likeliest
  // cause of an effect too small to matter at this tolerance (empty otherwise). Not the verdict.
  std::string below_tolerance;
  double below_tolerance_after_db = 0.0;  // its held-out gap
  RemainingGap remaining;
};

struct DiagnosisResult {
  std::string model_name;
  std::vector<std::size_t> heldout;    // condition indices scored (fired)
  std::vector<std::size_t> train;      // fired training conditions (all-training fit)
  std::vector<std::size_t> reference;  // motored runs
  bool leave_one_out = true;
  ModelScore baseline;
  std::vector<ModelScore> candidates;    // best first
  std::vector<ModelScore> combinations;  // two-effect sets tried
  Verdict verdict;
  Where where;
  double seconds = 0.0;
  std::vector<std::pair<std::string, double>> timing;  // stage, seconds
};

DiagnosisResult diagnose(const fit::BandDataset& data, const BlockParams& start, const std::string& model_name,
                         const DiagnosisOptions& options);

}  // namespace noisemon::model::diagnosis
