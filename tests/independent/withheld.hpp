// The withheld-effect family on the independent cell (cell_synth.hpp): the catalogue of cases (every effect the cell
// makes at two magnitudes, second modes at three frequencies and Q, and the null), and one case run through the REAL
// `noisemon diagnose` binary as a separate process, told nothing, its report.json scored.
//
// Scoring (issue 22): the PRIMARY verdict is what counts (verdict.effect; a partner in verdict.also does not
// rescue a wrong verdict), and the fitted parameters of the expected effect's candidate are checked where the effect
// has any a user would act on:
//   second_mode       the fitted mode_hz within a third octave (a factor 2^(1/3)) of the panel's frequency, mode_db > 0
//   mic_gain          the microphone with the largest fitted offset is the one with the error, its offset > 0
//   speed_dependence  the fitted gain slope > 0 and within a factor 2 of the truth's slope at 2000 rpm
//   cubic_stiffness, cubic_damping   the fitted k3 (b3) > 0: a hardening (a damping growing with the velocity)
//   transducer_noise  the fitted amplitude density at 1 kHz at least half the added noise's at 2000 rpm (the record's
//                     own floor is under it too, so only a lower bound is the truth's)
//   background_noise, mechanical_noise: no parameter a test engineer would read off (levels per band / window)
//
// The magnitudes are fixed here, before any diagnosis was run on them: the additive sources relative to the cell's
// engine level (the null run's array-average Lp(A) at 1800 rpm, a property of the synthesis alone).
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "cell_synth.hpp"

namespace indep {

struct Case {
  std::string label;
  std::string expect;  // the effect's name, or "none"
  Effects fx;
  int cell = 1;               // 1: default_conditions on Chain{}; 2: second_cell_conditions on second_cell_chain
  bool states_floor = false;  // run.json states the chain's commissioned floor (Chain::states_floor)
  // With the floor unstated, the bounds the diagnosis's estimate of the fired runs' floor (bar per 0.2 deg sample)
  // must keep: at least the added white noise's, at most the broadband floor of the whole chain (the record's own by
  // its second differences, with the added in quadrature); the record's own floor is not white, so its share in the
  // analysed bands is known only to lie between. NaN: not checked.
  double floor_at_least_bar = std::numeric_limits<double>::quiet_NaN(), floor_at_most_bar = floor_at_least_bar;
};

// The null run's array-average A-weighted level at 1800 rpm (fired, load 1), dB re 20 uPa.
double engine_level_dba(const Sources& src, const Chain& chain);

// The linear block's peak displacement and velocity in the same null run (what the block's nonlinearities are sized
// by), and its linear damping per kg.
struct ReferenceMotion {
  double z_peak_m = 0, v_peak_m_per_s = 0, b1_per_kg = 0;
};
ReferenceMotion reference_motion(const Sources& src, const Chain& chain);

// Every case of the catalogue (magnitudes of the additive ones relative to engine_dba).
std::vector<Case> withheld_cases(double engine_dba);
// The block's nonlinearities and the pressure chain's noise, sized by ref: a stop at half the peak displacement per
// stop ratio, quadratic drag adding `drag` times the linear damping force at the peak velocity, and white noise per
// 0.2 deg sample (bar) twice: beyond the floor run.json states (transducer_noise) and with no floor stated (`none`:
// the diagnosis estimates the floor, checked against Case::floor_at_least_bar and floor_at_most_bar; chain_floor_bar:
// the fired record's broadband floor with the chain's added noise); and the null with the floor stated. Labels start
// with prefix.
std::vector<Case> block_and_chain_cases(const ReferenceMotion& ref, int cell, const std::string& prefix,
                                        const std::vector<double>& stop_ratios, const std::vector<double>& drags,
                                        const std::vector<double>& noises_bar, double chain_floor_bar);
// The second cell's cases (labels "cell2_..."): its null, two modes, a microphone, a background, the speed and the
// impacts, one magnitude each, fixed before any diagnosis ran on that cell; engine_dba: its own engine's level.
std::vector<Case> second_cell_cases(double engine_dba);

// A cell's whole catalogue (1: withheld_cases with the block's and the chain's at two magnitudes; 2: second_cell_cases
// with one of each), sized by that cell's own engine level and reference motion at seed 1.
std::vector<Case> cell_catalogue(const Sources& src, int cell);

struct Outcome {
  std::string effect;             // verdict.effect
  std::vector<std::string> also;  // verdict.also
  std::string below_tolerance;    // verdict.below_tolerance: named beside `none`, not scored
  double before_db = 0, after_db = 0, closed = 0;
  bool verdict_right = false;   // the primary verdict is the expected effect
  bool params_checked = false;  // the effect has parameters to check
  bool params_right = false;
  std::string params;     // what was fitted, against the truth
  std::string runner_up;  // the best candidate that is not the verdict, with its gap
  double seconds = 0;
  std::string error;  // non-empty: diagnose failed (its log's tail)
};

// Writes the case's campaign (its cell's; the chain's seed and the records' cycles: `seed`, see default_conditions)
// under dir/runs, runs `noisemon diagnose` into dir/diag and scores its report.
Outcome diagnose_case(const Sources& src, const Case& c, std::uint64_t seed, const std::filesystem::path& dir,
                      const std::string& noisemon_path);

// One line of a Markdown table for a case's outcome, and the header it goes under.
std::string table_header();
std::string table_row(const Case& c, std::uint64_t seed, const Outcome& o);

}  // namespace indep
