// The stages of the band diagnosis (diagnosis.hpp), in the order diagnose() runs them, and what they hand on.
// Internal to model/diagnosis (and its unit tests): the public API is diagnosis.hpp.
//
//   roles_and_floors.cpp  which condition trains, is held out, is a reference or a floor; the cells at a floor
//   gap.cpp               the held-out gap of one condition (three parts) and the bootstrap draws over cycles
//   evaluation.cpp        one model tuned on the training conditions, on every fold, scored on the held-out ones
//   motored_law.cpp       an additive candidate never louder than what the motored runs hear, a pressure-driven one
//                         never predicting them worse than the baseline: else refuted
//   baseline.cpp          the start model tuned and scored: the gap every candidate is measured against
//   candidates.cpp        each effect added to the baseline, judged against it and ranked; pairs on top of the best
//   verdict.cpp           none, the effect (with its partner) or unexplained
//   remaining.cpp         what the verdict leaves: where the remaining gap lies, how it scales
//   where.cpp             where the baseline's gap lies: bands, conditions, input level, speed, microphones, windows
//   diagnosis.cpp         diagnose(): the stages in order, progress and timing
#pragma once

#include <chrono>
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "dsp/math_constants.hpp"
#include "model/diagnosis/diagnosis.hpp"
#include "model/fit/band_dataset.hpp"
#include "model/fit/band_fit.hpp"
#include "model/fit/pressure_floor.hpp"

namespace noisemon::model::diagnosis {

inline constexpr std::size_t kW = fit::kCrankWindows;

double db(double ratio);               // 10 log10(ratio)
double median(std::vector<double> v);  // NaN when empty

// Everything computed once per diagnosis by the first stages, for the others.
struct Context {
  const fit::BandDataset* data = nullptr;
  const DiagnosisOptions* opt = nullptr;
  // Roles (assign_roles), condition indices in dataset order.
  std::vector<std::size_t> fired, refs, backgrounds;  // fired, motored (references), engine off (floors)
  std::vector<std::size_t> train_fired, heldout;      // fired training conditions; the scored ones
  bool loo = true;                                    // leave-one-condition-out
  // Leave-one-group-out (assign_roles): the held-out conditions (indices into heldout) grouped by operating speed;
  // empty when the groups would be single conditions or one group, or under a given split.
  std::vector<std::vector<std::size_t>> groups;
  // Bands and floors (mark_bands_and_floors), per condition and band unless said otherwise.
  std::vector<double> background_ms;                // per band: the background runs' mean microphone level, Pa^2
  std::vector<std::vector<double>> motored_excess;  // motored runs only: measured beyond the model, Pa^2 (the start
                                                    // model's, then the tuned block's: remark_noise_dominated)
  std::vector<std::vector<char>> base_mask, tune_mask, floor_limited, noise_dominated;
  std::vector<std::string> band_notes;  // per band: "nyquist_cut", "line_free" or ""
  std::vector<char> fast;               // per band: fast enough for a crank window
  // The pressure chain's floor per condition, and the cells it limits (see pressure_floor.hpp).
  std::vector<fit::PressureFloor> pressure_floors;
  std::vector<std::vector<char>> pfloor_band;         // per condition, per band: cycle-mean pressure within the margin
  std::vector<std::vector<char>> pfloor_win;          // per condition, per band * W: the window's pressure likewise
  std::vector<std::vector<std::vector<int>>> counts;  // bootstrap draws (draw_bootstrap): [replicate][heldout][cycle]
  // Where the time goes (seconds, summed over models).
  mutable double t_fit = 0, t_folds = 0, t_heldout = 0, t_groups = 0, t_floors = 0, t_bootstrap = 0;
};

// Progress lines (DiagnosisOptions::progress) and the stage timing of a diagnosis (DiagnosisResult::timing).
class StageLog {
 public:
  using clock = std::chrono::steady_clock;
  StageLog(const DiagnosisOptions& opt, DiagnosisResult& res);
  void say(const std::string& line) const;
  void stage(const std::string& name);  // the time since the last stage ended, under this name
  double seconds() const;               // since the start
 private:
  const DiagnosisOptions* opt_;
  DiagnosisResult* res_;
  clock::time_point start_, last_;
};

// ---------------------------------------------------------------------------------------- roles and floors

// Fired, motored and background runs; the training and held-out conditions. Throws std::invalid_argument when a
// pattern matches nothing or there is nothing to train on or to hold out.
void assign_roles(Context& cx);
// The cells every model is fitted and scored on: background level, motored runs' excess over the start model,
// pressure floors, fast bands, masks and band notes.
void mark_bands_and_floors(Context& cx, const BlockParams& start);

// The motored runs' excess judged again beyond the tuned block (what the motored runs hear beyond the model's
// prediction from their pressure, not beyond the start model's, which may be far from the engine): the noise-dominated
// cells and the tuning mask follow. True when the tuning mask changed (the baseline is then tuned again).
bool remark_noise_dominated(Context& cx, const BlockParams& tuned);

// ---------------------------------------------------------------------------------------- the gap

// The measured side of a condition, corrected by a model's microphone gains.
struct Measured {
  std::vector<double> meas;  // [c * nb + b] microphone average
  std::vector<double> mic;   // [(c * M + m) * nb + b]
  std::vector<double> win;   // [(c * W + w) * nb + b] microphone average per window
};
Measured measured_side(const fit::ConditionData& d, const fit::ExtendedModel& m);

// Per-microphone offsets from the array (mean over the scored bands of 10 log10(mic / array mean)), cycles
// weighted by counts (nullptr: every cycle once).
std::vector<double> mic_offsets(const fit::ConditionData& d, const Measured& ms, const std::vector<char>& scored,
                                const std::vector<int>* counts);
// The part of each offset beyond the array's own robust spread (soft threshold at 3 sigma).
std::vector<double> mic_outliers(const std::vector<double>& off);

// The three parts of the gap in squares: thesis band gap (mean square), microphone calibration (sum of squares),
// crank windows (mean square).
struct Parts {
  double band_ms = 0.0, mic = 0.0, window_ms = 0.0;
  double total() const { return band_ms + mic + window_ms; }
};

struct ScoreDetail {
  std::vector<double> gaps;       // per band
  std::vector<double> mic_resid;  // per microphone
  std::vector<double> window;     // per window
  std::vector<double> cell;       // per window * bands + band (NaN where not scored)
};

// The three parts of the held-out gap of one condition (see diagnosis.hpp); floor: per band, the stationary
// floor the model leaves in the windows; counts: the bootstrap's cycle weights (nullptr: every cycle once).
Parts score_condition(const fit::ConditionData& d, const Measured& ms, const fit::ConditionPrediction& p,
                      const std::vector<char>& scored, const std::vector<char>& fast, const std::vector<double>& floor,
                      const std::vector<int>* counts, ScoreDetail* detail);

// The held-out cells a model was scored on (finite band and crank-window gaps, microphones) into m.heldout_cells,
// and its information criterion, n ln(gap^2) + parameters ln(n), into m.information_criterion: the likelihood of
// n Gaussian cells whose rms is the held-out gap, charged for every free level.
void set_information_criterion(ModelScore& m);

// The bootstrap over cycles: DiagnosisOptions::bootstrap draws per held-out condition, the same for every model.
void draw_bootstrap(Context& cx);

// ---------------------------------------------------------------------------------------- evaluation

// A model extension to try: effect names, the extensions switched on and the block parameters freed on top.
struct CandidateSpec {
  std::string name;
  std::vector<std::string> effects;
  fit::ExtensionSet ext;
  std::vector<fit::BlockParam> extra_free;
};

struct Evaluated {
  ModelScore score;
  std::vector<fit::ConditionPrediction> preds;  // per held-out condition
  std::vector<Measured> measured;               // per held-out condition
  std::vector<std::vector<double>> floors;      // per held-out condition: stationary floor per band
};

// Microphone gains from the conditions: the channels standing out of the array's spread.
std::vector<double> estimate_mic_gains(const Context& cx, const std::vector<std::size_t>& conds);
// Stationary floor the model leaves on the training data, per band (per held-out fold: without that condition).
std::vector<std::vector<double>> stationary_floors(const Context& cx, const fit::ExtendedModel& model);
// The spec's model fitted on the training conditions (and on every fold), its training figure, its held-out gap
// and the gap's bootstrap replicates.
Evaluated evaluate(const Context& cx, const CandidateSpec& spec, const fit::ExtendedModel& start,
                   const std::vector<fit::BlockParam>& base_free, bool is_baseline);

// Additive candidates (background, impacts): the fitted source alone against all the sound the motored runs measure,
// band by band; m.refuted when it claims more than they hear (ModelScore::motored_*).
void judge_motored_law(const Context& cx, ModelScore& m);
// Pressure-driven candidates (every one without an additive source): the motored runs predicted no worse than by the
// baseline, beyond their measurement's error and a margin; else m.refuted (ModelScore::motored_worse_*).
void judge_pressure_law(const Context& cx, const ModelScore& baseline, ModelScore& m);

// ---------------------------------------------------------------------------------------- baseline

Evaluated tune_baseline(const Context& cx, const BlockParams& start, const std::vector<fit::BlockParam>& base_free);
// The bootstrap spread (standard deviation over the replicates) of a model's held-out gap.
double bootstrap_noise_db(const ModelScore& m);

// ---------------------------------------------------------------------------------------- candidates

CandidateSpec spec_for(const std::string& name);
CandidateSpec combine(const CandidateSpec& a, const CandidateSpec& b);
// Improvement, significance and the parts closed of m against the reference (the baseline).
void compare_with(ModelScore& m, const ModelScore& ref, double min_improvement);
// Share of bootstrap replicates in which a's gap is below b's.
double beats(const ModelScore& a, const ModelScore& b);

struct CandidateRound {
  std::vector<CandidateSpec> specs;  // in the order tried
  std::vector<Evaluated> evals;      // likewise
  std::vector<std::size_t> order;    // ranking: indices into evals, best first
};
// Every candidate effect (DiagnosisOptions::candidates) evaluated on top of the baseline, judged against it and
// ranked.
CandidateRound evaluate_candidates(const Context& cx, const BlockParams& start, const Evaluated& base,
                                   const std::vector<fit::BlockParam>& base_free, StageLog& log);
// Ranking: held-out gap; a simpler significant candidate first when the better one does not beat it in 95 % of
// the replicates by at least min_improvement_db, or does not have the lower information criterion.
std::vector<std::size_t> rank_candidates(const std::vector<Evaluated>& evals, double min_improvement_db);
// The best significant candidate (sig[0]) with every other one, and the runner-up (sig[1]) likewise when it is
// close and no pair with the best reaches the tolerance. Appends to *combinations; returns the index there of
// the pair with the smallest gap (the first of equals; nullopt when none was tried).
std::optional<std::size_t> try_pairs(const Context& cx, const CandidateRound& round,
                                     const std::vector<std::size_t>& sig, const std::vector<fit::BlockParam>& base_free,
                                     const ModelScore& baseline, std::vector<ModelScore>* combinations,
                                     const StageLog& log);

// ---------------------------------------------------------------------------------------- verdict

// res.verdict from the baseline and the ranked candidates (pairs tried into res.combinations, the verdict's
// partner marked in res.candidates).
void judge(const Context& cx, const CandidateRound& round, const std::vector<fit::BlockParam>& base_free,
           DiagnosisResult& res, StageLog& log);

// What the model `after` leaves (remaining.cpp); band_rms: its per-band RMS over the held-out conditions.
RemainingGap describe_remaining(const Context& cx, const ModelScore& after, const std::vector<double>& band_rms);

// ---------------------------------------------------------------------------------------- where

// A condition's overall cylinder pressure level, dB re 20 uPa: the cycle-mean band powers below the Nyquist cut.
double overall_cpl_db(const fit::BandDataset& data, const fit::ConditionData& d);
// The mean of the finite values (NaN when there is none).
double mean_finite(const std::vector<double>& v);
// Least-squares slope of y over x; pairs with an unknown (NaN) member are left out; NaN with fewer than two.
double linear_slope(const std::vector<double>& xs, const std::vector<double>& ys);
// The floors in the report (Where's pressure_floor_*, floor_limited_*, mic_floor_*, floor_summary).
void report_floors(const Context& cx, Where& wh);
// res.where from the context, the baseline and the verdict's per-band gaps.
void describe_where(const Context& cx, const Evaluated& base, DiagnosisResult& res);

}  // namespace noisemon::model::diagnosis
