// Which unmodelled effect a change of the sim-to-real gap is: the live gap watch's attribution (noisemon gapwatch).
//
// The watch hands over what the cycle reports carry, averaged before the change (its reference) and after it:
// per 1/3-octave band the measured and predicted A-weighted levels and the cylinder pressure level, per microphone
// its overall A-weighted level. Each candidate of `noisemon diagnose` (the effect list, docs/diagnosis.md) predicts how
// those move, with a few parameters fitted by weighted least squares on the change:
//   mic_gain          one microphone reads G dB more: its level rises G, the array's energy mean rises by its share
//                     (2 parameters: which microphone, G)
//   transducer_noise  white noise of density D in the measured pressure: CPL rises 10 lg(1 + D bw / CPL) per band,
//                     the prediction follows it, the microphones do not (1: D; reported as bar rms per encoder sample)
//   background_noise  additive sound at every microphone, per band (a parameter per band it raises): stationary
//   mechanical_noise  test-cell noise, or crank-angle-locked impacts: told apart by the crank windows' levels (one
//                     power raising every window, against a power per window where it pays, by the same criterion);
//                     without windows (older logs), by the spectrum's centre (below 1 kHz: the test cell's)
//   second_mode       a further resonance in phase (f2, its level M, Q), on the block's output (|1 + g R|^2) or
//                     driven by the pressure beside the model's block (|H + g R|^2 / |H|^2), the better of the two
//                     (`parallel` 0 or 1) (3 parameters)
//   speed_dependence  the structural transfer's gain changes by the same dB in every band (1)
//   cubic_damping     the block's damping or stiffness rises (an amplitude-dependent term's effective linear part
//   cubic_stiffness   at this amplitude): the model block's |H(f)|^2 with b1 or k1 raised, over its own (1 each)
// Each fit's chi-square on the change (its standard errors from the reference's block-to-block spread, plus a
// model-error floor) and a Bayesian information criterion (chi2 + p ln n) rank them; the confidence is the
// named candidate's Schwarz weight among all of them and "no change". The change is `unexplained` when the best
// candidate closes less than half of the change's weighted size.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "model/block_params.hpp"

namespace noisemon::model::diagnosis {

struct GapChange {
  std::vector<double> band_hz;                            // nominal centres
  std::vector<char> band_used;                            // watched (finite before and after)
  std::vector<double> measured_before, measured_after;    // per band, dB
  std::vector<double> predicted_before, predicted_after;  // per band, dB
  std::vector<double> cpl_before, cpl_after;              // per band, dB re 20 uPa
  std::vector<double> band_sigma_db;                      // standard error of (after - before) of a band's gap, dB
  std::vector<double> cpl_sigma_db;                       // of a band's CPL, dB
  std::vector<double> mic_before, mic_after;              // per microphone, dB(A); NaN: not usable
  std::vector<double> mic_sigma_db;                       // standard error of (after - before) of its offset, dB
  std::vector<double> window_before, window_after;        // per crank window, measured dB(A); empty: not reported
  std::vector<double> window_sigma_db;
  double speed_rpm = 0.0;
  double pressure_edge_rate_hz = 0.0;  // encoder edges per second (0: unknown; transducer D as density)
};

struct AttributionOptions {
  BlockParams model_block = preset("linear");  // the daemon's model (the cubic candidates' templates)
  double model_error_db = 0.15;                // added in quadrature to every standard error
  double min_explained = 0.5;                  // the best candidate closes at least this share of the change
};

struct CandidateFit {
  std::string effect;  // candidate name, or "none"
  std::vector<std::pair<std::string, double>> params;
  int parameters = 0;
  double chi2 = 0.0;
  double criterion = 0.0;  // chi2 + parameters ln(n)
  double weight = 0.0;     // Schwarz weight among the candidates
};

struct Attribution {
  std::string effect;  // the named candidate, or "unexplained"
  std::vector<std::pair<std::string, double>> params;
  double confidence = 0.0;
  double explained = 0.0;                // 1 - chi2(best) / chi2(none)
  std::vector<CandidateFit> candidates;  // best first
  std::string explanation;               // one sentence
};

[[nodiscard]] Attribution attribute_change(const GapChange& change, const AttributionOptions& options = {});

}  // namespace noisemon::model::diagnosis
