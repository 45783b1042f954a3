#include "model/diagnosis/waveform_diagnosis.hpp"
#include "dsp/math_constants.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <stdexcept>

#include "dsp/welch.hpp"
#include "model/diagnosis/explainable_gap.hpp"

namespace noisemon::model::diagnosis {
namespace {

std::string fmt(const char* f, double a, double b = 0.0, double c = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

fit::WaveformSimOptions with_steps(fit::WaveformSimOptions sim, int steps) {
  sim.steps_per_sample = steps;
  return sim;
}

// Scored errors (model - measured) of each range.
std::vector<std::vector<double>> errors_of(const fit::WaveformModel& m, double fs, const fit::WaveformSimOptions& sim,
                                           std::span<const double> u, std::span<const double> y,
                                           std::span<const fit::SampleRange> ranges) {
  std::vector<std::vector<double>> out;
  for (const fit::SampleRange& r : ranges) {
    const auto s = simulate_waveform(m, fs, sim, u, y, r);
    std::vector<double> e;
    e.reserve(s.size() - sim.settle_samples);
    for (std::size_t j = sim.settle_samples; j < s.size(); ++j) e.push_back(s[j] - y[r.begin + j]);
    out.push_back(std::move(e));
  }
  return out;
}

// ------------------------------------------------------------------------------------------- spectra

// Frequency where most of the residual's power is coherent with the input, |S_ue|^2 / S_uu (the power the
// residual's transfer function from the input explains), between a few bins and 0.45 fs: where a missing
// mode shows. (The transfer function alone peaks wherever the input has little power.)
double residual_peak_hz(const std::vector<std::vector<double>>& u, const std::vector<std::vector<double>>& e,
                        double fs) {
  const std::size_t nfft = dsp::welch_nfft(u);
  std::vector<std::complex<double>> sue;
  std::vector<double> suu;
  if (dsp::welch(u, e, nfft, sue, suu) == 0) return 0.1 * fs;
  double best = -1.0, f_best = 0.1 * fs;
  double suu_max = 0.0;
  for (double v : suu) suu_max = std::max(suu_max, v);
  for (std::size_t k = 3; k <= nfft / 2; ++k) {
    const double f = fs * static_cast<double>(k) / static_cast<double>(nfft);
    if (f > 0.45 * fs) break;
    if (suu[k] < 1e-6 * suu_max) continue;  // no excitation there: the ratio is noise
    const double h = std::norm(sue[k]) / suu[k];
    if (h > best) {
      best = h;
      f_best = f;
    }
  }
  return f_best;
}

// --------------------------------------------------------------------------------------- candidates

struct CandidateSpec {
  std::string effect;
  fit::WaveformModel start;
  std::vector<std::string> added;
  std::string start_note;
};

bool has(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

// The candidate `effect` on top of `base` (fitted with free parameters `base_free`); nullopt when the base
// already contains it.
std::optional<CandidateSpec> make_candidate(const std::string& effect, const fit::WaveformFitResult& base,
                                            const std::vector<std::string>& base_free,
                                            const std::vector<std::vector<double>>& train_u,
                                            const std::vector<std::vector<double>>& train_e, double fs) {
  CandidateSpec c;
  c.effect = effect;
  c.start = base.model;
  const bool offsets = has(base_free, "y_offset") && !has(base_free, "u_offset");
  if (effect == "cubic_stiffness" || effect == "cubic_damping") {
    const std::string p = effect == "cubic_stiffness" ? "k3" : "b3";
    if (has(base_free, p)) return std::nullopt;
    c.start.block.k3 = effect == "cubic_stiffness" ? 0.0 : c.start.block.k3;
    c.start.block.b3 = effect == "cubic_damping" ? 0.0 : c.start.block.b3;
    c.added.push_back(p);
    if (offsets) c.added.push_back("u_offset");
  } else if (effect == "second_mode") {
    if (base.model.has_second_mode) return std::nullopt;
    const double f2 = residual_peak_hz(train_u, train_e, fs);
    c.start_note = fmt("second mode started at %.4g Hz (peak of the residual's power coherent with the input)", f2);
    const double w2 = 2.0 * std::numbers::pi * f2;
    c.start.has_second_mode = true;
    c.start.second = SecondModeParams{w2 * w2, 2.0 * 0.05 * w2, 0.0, 0.0};
    c.added = {"k1_2", "b1_2", "c0_2", "c1_2"};
  } else {
    throw std::invalid_argument("waveform diagnosis: unknown candidate effect '" + effect +
                                "' (waveform mode knows cubic_stiffness, cubic_damping, second_mode)");
  }
  return c;
}

void rank(std::vector<CandidateResult>& c, double tie) {
  std::stable_sort(c.begin(), c.end(), [](const CandidateResult& a, const CandidateResult& b) {
    if (a.significant != b.significant) return a.significant;
    return a.heldout_rms < b.heldout_rms;
  });
  // Tie-breaker: of two neighbours within `tie` of each other, the simpler first.
  for (bool swapped = true; swapped;) {
    swapped = false;
    for (std::size_t i = 0; i + 1 < c.size(); ++i) {
      CandidateResult& a = c[i];
      CandidateResult& b = c[i + 1];
      if (a.significant == b.significant && b.added_params.size() < a.added_params.size() &&
          std::fabs(a.heldout_rms - b.heldout_rms) <= tie * a.heldout_rms) {
        std::swap(a, b);
        swapped = true;
      }
    }
  }
}

std::vector<CandidateResult> run_round(const fit::WaveformFitResult& base, const std::vector<std::string>& base_free,
                                       const std::vector<std::string>& effects,
                                       const std::vector<std::vector<double>>& base_held_errors,
                                       std::span<const double> u, std::span<const double> y,
                                       const WaveformDiagnosisOptions& opt) {
  // Training signals for the second mode's start frequency.
  std::vector<std::vector<double>> train_u, train_e;
  if (has(effects, "second_mode")) {
    train_e = errors_of(base.model, opt.fs_hz, with_steps(opt.sim, base.steps_per_sample), u, y, opt.train);
    for (const fit::SampleRange& r : opt.train)
      train_u.emplace_back(u.begin() + static_cast<std::ptrdiff_t>(r.begin + opt.sim.settle_samples),
                           u.begin() + static_cast<std::ptrdiff_t>(r.end));
  }
  const double before = rms_of(base_held_errors);
  std::vector<CandidateResult> out;
  for (const std::string& effect : effects) {
    const auto spec = make_candidate(effect, base, base_free, train_u, train_e, opt.fs_hz);
    if (!spec) continue;
    CandidateResult c;
    c.effect = effect;
    c.added_params = spec->added;
    fit::WaveformFitOptions fo;
    fo.fs_hz = opt.fs_hz;
    fo.train = opt.train;
    fo.heldout = opt.heldout;
    fo.free_params = base_free;
    fo.free_params.insert(fo.free_params.end(), spec->added.begin(), spec->added.end());
    fo.start = spec->start;
    fo.start_name = "baseline + " + effect;
    fo.sim = opt.sim;
    fo.max_iterations = opt.max_iterations;
    fo.progress = opt.fit_progress;
    if (opt.log) {
      opt.log("fitting candidate " + effect + " (+" + std::to_string(spec->added.size()) + " parameters)");
      if (!spec->start_note.empty()) opt.log(spec->start_note);
    }
    try {
      c.fit = fit::fit_waveform(u, y, fo);
      const auto held =
          errors_of(c.fit.model, opt.fs_hz, with_steps(opt.sim, c.fit.steps_per_sample), u, y, opt.heldout);
      c.heldout_rms = rms_of(held);
      c.heldout_segment_rms = c.fit.heldout_segment_rms;
      c.gap_closed_fraction = 1.0 - c.heldout_rms / before;
      c.test = block_bootstrap_test(squared_difference(base_held_errors, held), opt.block_samples,
                                    opt.bootstrap_resamples, opt.seed);
    } catch (const std::exception& e) {
      c.error = e.what();
      c.heldout_rms = kInf;
      c.gap_closed_fraction = 0.0;
    }
    if (opt.log)
      opt.log(c.error.empty() ? effect + fmt(": held-out rms %.6g (%.1f %% of the gap closed), p = %.4f", c.heldout_rms,
                                             100.0 * c.gap_closed_fraction, c.test.p_value)
                              : effect + ": fit failed: " + c.error);
    out.push_back(std::move(c));
  }
  const double k = static_cast<double>(std::max<std::size_t>(out.size(), 1));
  for (CandidateResult& c : out)
    c.significant = c.error.empty() && c.test.p_value < opt.alpha / k && c.gap_closed_fraction >= opt.min_gain;
  rank(out, opt.tie_tolerance);
  return out;
}

// ------------------------------------------------------------------------------------------- diagnosis

void check_options(const WaveformDiagnosisOptions& opt) {
  if (opt.heldout.empty()) throw std::invalid_argument("waveform diagnosis: no held-out range");
  for (const std::string& c : opt.candidates)
    if (c != "cubic_stiffness" && c != "cubic_damping" && c != "second_mode")
      throw std::invalid_argument("waveform diagnosis: candidate '" + c +
                                  "' does not apply to a waveform (waveform mode knows cubic_stiffness, "
                                  "cubic_damping, second_mode)");
}

std::vector<NotApplicable> not_applicable_effects() {
  return {
      {"mechanical_noise", "crank-angle-locked impacts: a u,y waveform carries no crank angle"},
      {"background_noise",
       "output noise independent of the input: no model extension reduces a free-run error; "
       "it is the floor the explainable-gap test measures against"},
      {"transducer_noise", "noise on the measured input: irreducible by a model of the system (errors in variables)"},
      {"mic_gain", "a single output channel: a gain error is absorbed by c0 and c1"},
      {"speed_dependence", "no engine speed in a waveform"},
  };
}

fit::WaveformFitResult fit_baseline(std::span<const double> u, std::span<const double> y,
                                    const WaveformDiagnosisOptions& opt) {
  fit::WaveformFitOptions fo;
  fo.fs_hz = opt.fs_hz;
  fo.train = opt.train;
  fo.heldout = opt.heldout;
  fo.free_params = opt.baseline_free;
  fo.start = opt.start;
  fo.start_name = opt.start_name;
  fo.sim = opt.sim;
  fo.max_iterations = opt.max_iterations;
  fo.progress = opt.fit_progress;
  if (opt.log) opt.log("fitting the baseline (" + std::to_string(opt.baseline_free.size()) + " parameters)");
  return fit::fit_waveform(u, y, fo);
}

// The second round on top of the verdict's candidate `best`: the best model becomes the verdict's effect plus the
// best significant one fitted on top of it. Updates best_held and best_sim with it.
void second_round_on_top(WaveformDiagnosis& d, const CandidateResult& best, std::vector<std::vector<double>>& best_held,
                         fit::WaveformSimOptions& best_sim, std::span<const double> u, std::span<const double> y,
                         const WaveformDiagnosisOptions& opt) {
  std::vector<std::string> rest;
  for (const std::string& c : opt.candidates)
    if (c != best.effect) rest.push_back(c);
  std::vector<std::string> best_free = best.fit.free_params;
  d.second_round = run_round(best.fit, best_free, rest, best_held, u, y, opt);
  for (const auto& c : d.second_round)
    if (c.significant) d.also_significant.push_back(c.effect);
  if (!d.second_round.empty() && d.second_round.front().significant) {
    const CandidateResult& top = d.second_round.front();
    d.best_model = top.fit.model;
    d.best_steps_per_sample = top.fit.steps_per_sample;
    best_sim = with_steps(opt.sim, top.fit.steps_per_sample);
    d.heldout_rms_after = top.heldout_rms;
    best_held = errors_of(d.best_model, opt.fs_hz, best_sim, u, y, opt.heldout);
  }
}

// The verdict and the best model (the best significant candidate, else the baseline: `unexplained` when its error
// is significantly explainable from the input, `none` otherwise) and what remains explainable after it. Returns
// the best model's held-out errors.
std::vector<std::vector<double>> choose_best(WaveformDiagnosis& d, const std::vector<std::vector<double>>& base_held,
                                             std::span<const double> u, std::span<const double> y,
                                             const WaveformDiagnosisOptions& opt) {
  const CandidateResult* best =
      (!d.candidates.empty() && d.candidates.front().significant) ? &d.candidates.front() : nullptr;
  if (!best) {
    d.verdict = d.baseline_gap.significant ? "unexplained" : "none";
    d.best_model = d.baseline.model;
    d.best_steps_per_sample = d.baseline.steps_per_sample;
    d.heldout_rms_after = d.heldout_rms_before;
    d.remaining_gap = d.baseline_gap;
    return base_held;
  }
  d.verdict = best->effect;
  d.best_model = best->fit.model;
  d.best_steps_per_sample = best->fit.steps_per_sample;
  fit::WaveformSimOptions best_sim = with_steps(opt.sim, best->fit.steps_per_sample);
  std::vector<std::vector<double>> best_held = errors_of(d.best_model, opt.fs_hz, best_sim, u, y, opt.heldout);
  d.heldout_rms_after = best->heldout_rms;
  if (opt.second_round) second_round_on_top(d, *best, best_held, best_sim, u, y, opt);
  d.remaining_gap = explainable_gap(d.best_model, opt.fs_hz, opt, best_sim, u, y);
  return best_held;
}

// Per 1/3-octave band of the held-out output: its rms and the baseline's and the best model's error rms.
std::vector<BandGap> band_gaps(const std::vector<std::vector<double>>& y_held,
                               const std::vector<std::vector<double>>& base_held,
                               const std::vector<std::vector<double>>& best_held, double fs_hz) {
  const auto out_bands = dsp::third_octave_rms(y_held, fs_hz);
  const auto before_bands = dsp::third_octave_rms(base_held, fs_hz);
  const auto after_bands = dsp::third_octave_rms(best_held, fs_hz);
  std::vector<BandGap> bands;
  for (std::size_t b = 0; b < out_bands.size() && b < before_bands.size() && b < after_bands.size(); ++b)
    bands.push_back({out_bands[b].f_center_hz, out_bands[b].f_lo_hz, out_bands[b].f_hi_hz, out_bands[b].rms,
                     before_bands[b].rms, after_bands[b].rms});
  return bands;
}

// The errors against the local output level: rms over two periods of the primary mode, in five equally
// populated bins.
std::vector<AmplitudeGap> amplitude_gaps(const fit::WaveformModel& baseline,
                                         const std::vector<std::vector<double>>& y_held,
                                         const std::vector<std::vector<double>>& base_held,
                                         const std::vector<std::vector<double>>& best_held, double fs_hz) {
  const double fn = std::sqrt(baseline.block.k1 / baseline.block.m) / (2.0 * std::numbers::pi);
  const std::size_t win = static_cast<std::size_t>(std::clamp(std::round(2.0 * fs_hz / fn), 4.0, 1e5));
  std::vector<std::array<double, 3>> lv;  // level, error before, error after
  for (std::size_t s = 0; s < y_held.size(); ++s) {
    const auto& yy = y_held[s];
    double mean = 0.0;
    for (double v : yy) mean += v;
    mean /= static_cast<double>(std::max<std::size_t>(yy.size(), 1));
    double acc = 0.0;
    std::vector<double> level(yy.size());
    for (std::size_t i = 0; i < yy.size(); ++i) {
      acc += (yy[i] - mean) * (yy[i] - mean);
      if (i >= win) acc -= (yy[i - win] - mean) * (yy[i - win] - mean);
      level[i] = std::sqrt(std::max(acc, 0.0) / static_cast<double>(std::min(i + 1, win)));
    }
    for (std::size_t i = 0; i < yy.size(); ++i) lv.push_back({level[i], base_held[s][i], best_held[s][i]});
  }
  std::sort(lv.begin(), lv.end(), [](const auto& a, const auto& b) { return a[0] < b[0]; });
  constexpr std::size_t kLevelBins = 5;
  std::vector<AmplitudeGap> out;
  for (std::size_t b = 0; b < kLevelBins && lv.size() >= kLevelBins; ++b) {
    const std::size_t i0 = lv.size() * b / kLevelBins, i1 = lv.size() * (b + 1) / kLevelBins;
    AmplitudeGap g;
    g.level_lo = lv[i0][0];
    g.level_hi = lv[i1 - 1][0];
    g.samples = i1 - i0;
    double sb = 0.0, sa = 0.0;
    for (std::size_t i = i0; i < i1; ++i) {
      sb += lv[i][1] * lv[i][1];
      sa += lv[i][2] * lv[i][2];
    }
    g.error_rms_before = std::sqrt(sb / static_cast<double>(g.samples));
    g.error_rms_after = std::sqrt(sa / static_cast<double>(g.samples));
    out.push_back(g);
  }
  return out;
}

}  // namespace

// ------------------------------------------------------------------------------------------ public API

WaveformDiagnosis diagnose_waveform(std::span<const double> u, std::span<const double> y,
                                    const WaveformDiagnosisOptions& opt) {
  check_options(opt);
  const auto t0 = std::chrono::steady_clock::now();
  WaveformDiagnosis d;
  d.not_applicable = not_applicable_effects();

  d.baseline = fit_baseline(u, y, opt);
  const fit::WaveformSimOptions base_sim = with_steps(opt.sim, d.baseline.steps_per_sample);
  const auto base_held = errors_of(d.baseline.model, opt.fs_hz, base_sim, u, y, opt.heldout);
  d.heldout_rms_before = rms_of(base_held);
  if (opt.log) opt.log(fmt("baseline: train rms %.6g, held-out rms %.6g", d.baseline.train_rms, d.heldout_rms_before));

  d.candidates = run_round(d.baseline, opt.baseline_free, opt.candidates, base_held, u, y, opt);
  d.baseline_gap = explainable_gap(d.baseline.model, opt.fs_hz, opt, base_sim, u, y);
  if (opt.log)
    opt.log(fmt("baseline error explainable from the input: %.1f %% of its rms (p = %.4f)",
                100.0 * d.baseline_gap.fraction, d.baseline_gap.test.p_value));
  const std::vector<std::vector<double>> best_held = choose_best(d, base_held, u, y, opt);
  if (opt.log) opt.log("verdict: " + d.verdict);

  // Where: per held-out range, per band, against the output level.
  for (std::size_t s = 0; s < base_held.size(); ++s) {
    d.segment_rms_before.push_back(rms_of({base_held[s]}));
    d.segment_rms_after.push_back(rms_of({best_held[s]}));
  }
  std::vector<std::vector<double>> y_held;
  for (const fit::SampleRange& r : opt.heldout)
    y_held.emplace_back(y.begin() + static_cast<std::ptrdiff_t>(r.begin + opt.sim.settle_samples),
                        y.begin() + static_cast<std::ptrdiff_t>(r.end));
  d.bands = band_gaps(y_held, base_held, best_held, opt.fs_hz);
  d.amplitude = amplitude_gaps(d.baseline.model, y_held, base_held, best_held, opt.fs_hz);
  d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return d;
}

namespace {
std::vector<std::pair<std::string, double>> model_params(const fit::WaveformModel& m,
                                                         const std::vector<std::string>& free) {
  std::vector<std::pair<std::string, double>> out;
  for (const std::string& name : free) out.emplace_back(name, fit::get_parameter(m, name));
  return out;
}

WaveformReportCandidate report_candidate(const CandidateResult& c, bool second_round) {
  WaveformReportCandidate r;
  r.effect = c.effect;
  r.heldout_rms = c.heldout_rms;
  r.gap_closed_fraction = c.gap_closed_fraction;
  r.significant = c.significant;
  r.p_value = c.test.p_value;
  if (c.error.empty()) r.params = model_params(c.fit.model, c.fit.free_params);
  r.second_round = second_round;
  r.error = c.error;
  return r;
}
}  // namespace

WaveformReport waveform_report(const WaveformDiagnosis& d) {
  WaveformReport r;
  r.baseline_model = d.baseline.start_name;
  r.baseline_train_rms = d.baseline.train_rms;
  r.baseline_heldout_rms = d.baseline.heldout_rms;
  r.baseline_params = model_params(d.baseline.model, d.baseline.free_params);
  for (const CandidateResult& c : d.candidates) r.candidates.push_back(report_candidate(c, false));
  for (const CandidateResult& c : d.second_round) r.candidates.push_back(report_candidate(c, true));
  r.not_applicable = d.not_applicable;
  r.verdict = d.verdict;
  r.also_significant = d.also_significant;
  r.heldout_rms_before = d.heldout_rms_before;
  r.heldout_rms_after = d.heldout_rms_after;
  r.bands = d.bands;
  r.amplitude = d.amplitude;
  return r;
}

}  // namespace noisemon::model::diagnosis
