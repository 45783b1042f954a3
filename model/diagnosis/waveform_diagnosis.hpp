// Waveform-mode diagnosis: where and why the tuned block model disagrees with a measured input/output
// waveform, which unmodelled effect explains it, and how much of the gap it closes.
//
// Baseline: the model fitted on the training ranges (fit_waveform). Candidates, each the baseline plus one
// extension, all parameters refitted on the training ranges and scored by free-run RMS error on the held-out
// ranges (never on neighbouring samples of the training data):
//   cubic_stiffness  + k3 (and the input offset when offsets are fitted: a nonlinearity makes the input's
//                    operating point identifiable, which it is not for a linear model)
//   cubic_damping    + b3 (idem)
//   second_mode      + a linear mass-spring-damper in parallel on the output (k1_2, b1_2, c0_2, c1_2),
//                    started at the peak of the residual's transfer function from the input
// Not applicable to a single input/output waveform (listed in the result with the reason): mechanical_noise
// (no crank angle), background_noise and transducer_noise (noise independent of the input: no model
// extension reduces a free-run error; they are the floor the explainable-gap test measures against),
// mic_gain (one output channel: a gain error is absorbed by c0, c1), speed_dependence (no engine speed).
//
// Significance: the per-sample difference of squared held-out errors (baseline - candidate) is resampled
// in blocks of neighbouring samples within each held-out range (a block bootstrap, so the error's own
// correlation is respected); one-sided p-value for "the candidate reduces the mean squared error",
// Bonferroni over the candidates of a round. A candidate is significant when p < alpha / K and it reduces
// the held-out RMS by at least min_gain. Ranking: significant first, then by held-out RMS; candidates
// within tie_tolerance of each other are ordered by the number of added parameters (complexity).
// A second round fits the remaining candidates on top of the best one (two effects at once).
//
// Verdict: the best significant candidate; otherwise `unexplained` when the baseline's held-out error is
// significantly predictable from the input (the explainable-gap test: a regularised regression of the
// training error on lagged input, lagged square and cube of the model output and the model's own linear
// dynamics driven by them, scored on the held-out ranges), else `none` (the baseline agrees within the
// noise).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "model/diagnosis/block_bootstrap.hpp"
#include "model/fit/waveform_fit.hpp"

namespace noisemon::model::diagnosis {

struct WaveformDiagnosisOptions {
  double fs_hz = 0.0;
  std::vector<fit::SampleRange> train;
  std::vector<fit::SampleRange> heldout;
  std::vector<std::string> baseline_free = {"k1", "b1", "c0", "c1", "y_offset"};
  std::optional<fit::WaveformModel> start;  // nullopt: nearest preset or the data's linear estimate
  std::string start_name;
  fit::WaveformSimOptions sim;
  std::vector<std::string> candidates = {"cubic_stiffness", "cubic_damping", "second_mode"};
  int max_iterations = 40;
  double alpha = 0.05;
  double min_gain = 0.01;        // smallest held-out RMS reduction (fraction) that counts
  double tie_tolerance = 0.005;  // relative held-out RMS difference treated as a tie
  int bootstrap_resamples = 2000;
  std::size_t block_samples = 0;  // bootstrap block length; 0: from the error's correlation
  std::uint64_t seed = 1;
  bool second_round = true;
  std::function<void(const std::string&)> log;  // one line per step (nothing printed otherwise)
  std::function<void(const fit::WaveformFitProgress&)> fit_progress;
};

struct CandidateResult {
  std::string effect;
  std::vector<std::string> added_params;
  fit::WaveformFitResult fit;
  double heldout_rms = 0.0;
  std::vector<double> heldout_segment_rms;
  double gap_closed_fraction = 0.0;  // 1 - rms_after / rms_before on the held-out ranges
  SignificanceTest test;
  bool significant = false;
  std::string error;  // the fit failed (then heldout_rms is infinite and significant false)
};

// How much of an error the input can still explain (see the header comment).
struct ExplainableGap {
  double heldout_rms = 0.0;        // of the error
  double heldout_rms_after = 0.0;  // after subtracting its prediction from the input features
  double fraction = 0.0;           // 1 - after / before
  SignificanceTest test;
  bool significant = false;
};

struct BandGap {
  double f_center_hz = 0.0, f_lo_hz = 0.0, f_hi_hz = 0.0;
  double output_rms = 0.0;        // measured output in the band
  double error_rms_before = 0.0;  // baseline error
  double error_rms_after = 0.0;   // best model's error
};

struct AmplitudeGap {
  double level_lo = 0.0, level_hi = 0.0;  // local rms of the measured output (data units)
  std::size_t samples = 0;
  double error_rms_before = 0.0, error_rms_after = 0.0;
};

struct NotApplicable {
  std::string effect, reason;
};

struct WaveformDiagnosis {
  fit::WaveformFitResult baseline;
  std::vector<CandidateResult> candidates;    // ranked, best first
  std::vector<CandidateResult> second_round;  // on top of the best significant candidate, ranked
  std::vector<NotApplicable> not_applicable;
  ExplainableGap baseline_gap;   // of the baseline's held-out error
  ExplainableGap remaining_gap;  // of the best model's held-out error
  std::vector<BandGap> bands;
  std::vector<AmplitudeGap> amplitude;
  std::vector<double> segment_rms_before, segment_rms_after;
  std::string verdict;                        // effect name, "none" or "unexplained"
  std::vector<std::string> also_significant;  // second-round effects that are significant on top
  double heldout_rms_before = 0.0;
  double heldout_rms_after = 0.0;  // best model (the verdict's, plus the significant second-round one)
  fit::WaveformModel best_model;
  int best_steps_per_sample = 1;
  double seconds = 0.0;
};

WaveformDiagnosis diagnose_waveform(std::span<const double> u, std::span<const double> y,
                                    const WaveformDiagnosisOptions& opt);

// The diagnosis in report.json's shape (docs/diagnosis.md), for `noisemon diagnose` in waveform mode. The RMS
// figures are free-run output errors in the data's units (not dB): a writer puts them under the schema's *_rms_db keys
// only with a "units" field beside them. Candidates best first (the diagnosis' ranking), second-round ones after.
struct WaveformReportCandidate {
  std::string effect;
  double heldout_rms = 0.0;
  double gap_closed_fraction = 0.0;
  bool significant = false;
  double p_value = 1.0;
  std::vector<std::pair<std::string, double>> params;  // every parameter of the candidate's fitted model
  bool second_round = false;                           // fitted on top of the verdict's effect
  std::string error;                                   // the fit failed
};
struct WaveformReport {
  std::string units = "data units";
  std::string baseline_model;  // the start the baseline was fitted from (preset, "data", given name)
  double baseline_train_rms = 0.0, baseline_heldout_rms = 0.0;
  std::vector<std::pair<std::string, double>> baseline_params;
  std::vector<WaveformReportCandidate> candidates;
  std::vector<NotApplicable> not_applicable;
  std::string verdict;  // effect, "none" or "unexplained"
  std::vector<std::string> also_significant;
  double heldout_rms_before = 0.0, heldout_rms_after = 0.0;
  std::vector<BandGap> bands;           // "where": per 1/3-octave band of the output
  std::vector<AmplitudeGap> amplitude;  // "where": against the output level
};
WaveformReport waveform_report(const WaveformDiagnosis& d);

}  // namespace noisemon::model::diagnosis
