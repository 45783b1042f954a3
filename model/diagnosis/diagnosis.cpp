#include "model/diagnosis/diagnosis.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <stdexcept>

#include "dsp/weighting.hpp"
#include "model/fit/pressure_floor.hpp"

namespace noisemon::model {
namespace {

constexpr std::size_t kW = kCrankWindows;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kMicSpreadFloorDb = 0.1;  // robust spread of the array never taken below this
constexpr double kMicOutlierSigmas = 3.0;
constexpr double kPairShare = 0.2;  // a second effect must close this share of the best one's remaining gap
constexpr double kCloseRunnerUp = 1.5;  // a runner-up within this factor of the best gap starts pairs too
constexpr double kThesisWorseDb = 0.05;  // a model this much worse on the thesis metric is never significant

double db(double ratio) { return 10.0 * std::log10(ratio); }

double median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The measured side of a condition, corrected by a model's microphone gains.
struct Measured {
  std::vector<double> meas;  // [c * nb + b] microphone average
  std::vector<double> mic;   // [(c * M + m) * nb + b]
  std::vector<double> win;   // [(c * W + w) * nb + b] microphone average per window
};

Measured measured_side(const ConditionData& d, const ExtendedModel& m) {
  const std::size_t nb = d.bands, M = d.mics, nc = d.cycle_count();
  Measured r;
  r.meas.resize(nc * nb);
  r.mic = d.mic_ms;
  r.win = d.win_ms;
  const bool gains = m.on.mic_gain && m.ext.mic_gain_db.size() == M;
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t b = 0; b < nb; ++b) {
      double s = 0.0, raw = 0.0;
      for (std::size_t mi = 0; mi < M; ++mi) {
        double& x = r.mic[(c * M + mi) * nb + b];
        raw += x;
        if (gains) x *= std::pow(10.0, -m.ext.mic_gain_db[mi] / 10.0);
        s += x;
      }
      r.meas[c * nb + b] = s / static_cast<double>(M);
      if (gains && raw > 0)
        for (std::size_t w = 0; w < kW; ++w) r.win[(c * kW + w) * nb + b] *= s / raw;
    }
  return r;
}

// Per-microphone offsets from the array (mean over the scored bands of 10 log10(mic / array mean)).
std::vector<double> mic_offsets(const ConditionData& d, const Measured& ms, const std::vector<char>& scored,
                                const std::vector<int>* counts) {
  const std::size_t nb = d.bands, M = d.mics, nc = d.cycle_count();
  std::vector<double> mic_sum(M * nb, 0.0), avg(nb, 0.0), off(M, 0.0);
  for (std::size_t c = 0; c < nc; ++c) {
    const double w = counts ? (*counts)[c] : 1.0;
    if (w == 0) continue;
    for (std::size_t m = 0; m < M; ++m)
      for (std::size_t b = 0; b < nb; ++b) mic_sum[m * nb + b] += w * ms.mic[(c * M + m) * nb + b];
    for (std::size_t b = 0; b < nb; ++b) avg[b] += w * ms.meas[c * nb + b];
  }
  int n = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    if (!scored[b] || !(avg[b] > 0)) continue;
    ++n;
    for (std::size_t m = 0; m < M; ++m) off[m] += mic_sum[m * nb + b] > 0 ? db(mic_sum[m * nb + b] / avg[b]) : 0.0;
  }
  for (double& o : off) o = n > 0 ? o / n : 0.0;
  return off;
}

// The part of each offset beyond the array's own robust spread (soft threshold at 3 sigma).
std::vector<double> mic_outliers(const std::vector<double>& off) {
  const double med = median(off);
  std::vector<double> dev;
  for (double o : off) dev.push_back(std::abs(o - med));
  const double s = std::max(kMicSpreadFloorDb, 1.4826 * median(dev));
  std::vector<double> t(off.size());
  for (std::size_t i = 0; i < off.size(); ++i) {
    const double x = off[i] - med;
    t[i] = std::copysign(std::max(0.0, std::abs(x) - kMicOutlierSigmas * s), x);
  }
  return t;
}

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

// The three parts of the held-out gap of one condition (see diagnosis.hpp).
Parts score_condition(const ConditionData& d, const Measured& ms, const ConditionPrediction& p,
                      const std::vector<char>& scored, const std::vector<char>& fast, const std::vector<double>& floor,
                      const std::vector<int>* counts, ScoreDetail* detail) {
  const std::size_t nb = d.bands, nc = d.cycle_count();
  std::vector<double> m(nb, 0.0), q(nb, 0.0), mw(nb * kW, 0.0), qw(nb * kW, 0.0);
  double n = 0.0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double w = counts ? (*counts)[c] : 1.0;
    if (w == 0) continue;
    n += w;
    for (std::size_t b = 0; b < nb; ++b) {
      m[b] += w * ms.meas[c * nb + b];
      q[b] += w * p.cycle_ms[c * nb + b];
      if (!fast[b]) continue;
      for (std::size_t ww = 0; ww < kW; ++ww) {
        mw[b * kW + ww] += w * ms.win[(c * kW + ww) * nb + b];
        qw[b * kW + ww] += w * p.win_ms[(c * kW + ww) * nb + b];
      }
    }
  }
  Parts parts;
  if (detail) {
    detail->gaps.assign(nb, kNaN);
    detail->window.assign(kW, 0.0);
    detail->cell.assign(kW * nb, kNaN);
  }
  // Sampling variance of a cycle-averaged gap 10 log10(sum m / sum q) from the cycle-to-cycle scatter (delta
  // method): subtracting it from the squared gap leaves an unbiased estimate of the squared systematic gap, so
  // the noise of a few cycles does not count as disagreement.
  constexpr double kDb2 = (10.0 / std::numbers::ln10) * (10.0 / std::numbers::ln10);
  auto gap_variance = [&](auto get_m, auto get_q, double msum, double qsum, double add) {
    if (n < 2) return 0.0;
    const double mbar = msum / n, qbar = (qsum + n * add) / n;
    double s1 = 0.0, s2 = 0.0;
    for (std::size_t c = 0; c < nc; ++c) {
      const double w = counts ? (*counts)[c] : 1.0;
      if (w == 0) continue;
      const double r = get_m(c) / mbar - (get_q(c) + add) / qbar;
      s1 += w * r;
      s2 += w * r * r;
    }
    const double var = (s2 - s1 * s1 / n) / (n - 1.0);
    return kDb2 * std::max(0.0, var) / n;
  };
  int nbands = 0, nwin = 0;
  std::vector<double> wsum(kW, 0.0);
  std::vector<int> wcount(kW, 0);
  for (std::size_t b = 0; b < nb; ++b) {
    if (!scored[b] || !(m[b] > 0) || !(q[b] > 0)) continue;
    const bool ub = !p.upper.empty() && p.upper[b];
    const double g = ub ? std::max(0.0, db(m[b] / q[b])) : db(m[b] / q[b]);
    if (!ub) parts.band_ms -= gap_variance([&](std::size_t c) { return ms.meas[c * nb + b]; },
                                          [&](std::size_t c) { return p.cycle_ms[c * nb + b]; }, m[b], q[b], 0.0);
    parts.band_ms += g * g;
    ++nbands;
    if (detail) detail->gaps[b] = g;
    if (!fast[b]) continue;
    for (std::size_t ww = 0; ww < kW; ++ww) {
      const double den = qw[b * kW + ww] + n * floor[b];
      if (!(mw[b * kW + ww] > 0) || !(den > 0)) continue;
      const bool uw = !p.upper_win.empty() && p.upper_win[b * kW + ww];
      const double h = uw ? std::max(0.0, db(mw[b * kW + ww] / den)) : db(mw[b * kW + ww] / den);
      parts.window_ms += h * h;
      if (!uw) parts.window_ms -= gap_variance([&](std::size_t c) { return ms.win[(c * kW + ww) * nb + b]; },
                                              [&](std::size_t c) { return p.win_ms[(c * kW + ww) * nb + b]; },
                                              mw[b * kW + ww], qw[b * kW + ww], floor[b]);
      ++nwin;
      if (detail) detail->cell[ww * nb + b] = h;
      wsum[ww] += h;
      ++wcount[ww];
    }
  }
  parts.band_ms = nbands > 0 ? std::max(0.0, parts.band_ms / nbands) : 0.0;
  parts.window_ms = nwin > 0 ? std::max(0.0, parts.window_ms / nwin) : 0.0;
  const std::vector<double> t = mic_outliers(mic_offsets(d, ms, scored, counts));
  for (double x : t) parts.mic += x * x;
  if (detail) {
    detail->mic_resid = t;
    for (std::size_t ww = 0; ww < kW; ++ww) detail->window[ww] = wcount[ww] > 0 ? wsum[ww] / wcount[ww] : kNaN;
  }
  return parts;
}

struct CandidateSpec {
  std::string name;
  std::vector<std::string> effects;
  ExtensionSet ext;
  std::vector<BlockParam> extra_free;
};

CandidateSpec spec_for(const std::string& name) {
  CandidateSpec s;
  s.name = name;
  s.effects = {name};
  if (name == "cubic_damping") s.extra_free = {BlockParam::kB3};
  else if (name == "cubic_stiffness") s.extra_free = {BlockParam::kK3};
  else if (name == "second_mode") s.ext.second_mode = true;
  else if (name == "mechanical_noise") s.ext.locked = true;
  else if (name == "background_noise") s.ext.stationary = true;
  else if (name == "transducer_noise") s.ext.transducer = true;
  else if (name == "mic_gain") s.ext.mic_gain = true;
  else if (name == "speed_dependence") s.ext.speed = true;
  else throw std::invalid_argument("unknown candidate effect '" + name + "'");
  return s;
}

CandidateSpec combine(const CandidateSpec& a, const CandidateSpec& b) {
  CandidateSpec s = a;
  s.name = a.name + "+" + b.name;
  s.effects.insert(s.effects.end(), b.effects.begin(), b.effects.end());
  s.ext.second_mode |= b.ext.second_mode;
  s.ext.speed |= b.ext.speed;
  s.ext.transducer |= b.ext.transducer;
  s.ext.stationary |= b.ext.stationary;
  s.ext.locked |= b.ext.locked;
  s.ext.mic_gain |= b.ext.mic_gain;
  for (BlockParam p : b.extra_free)
    if (std::find(s.extra_free.begin(), s.extra_free.end(), p) == s.extra_free.end()) s.extra_free.push_back(p);
  return s;
}

// Everything computed once per diagnosis.
struct Context {
  const BandDataset* data = nullptr;
  const DiagnosisOptions* opt = nullptr;
  std::vector<std::size_t> train_fired, refs, heldout;
  bool loo = true;
  std::vector<std::vector<char>> base_mask, tune_mask, floor_limited, noise_dominated;
  std::vector<char> fast;
  // The pressure chain's floor per condition, and the cells it limits (see pressure_floor.hpp).
  std::vector<PressureFloor> pressure_floors;
  std::vector<std::vector<char>> pfloor_band;  // per condition, per band: cycle-mean pressure within the margin
  std::vector<std::vector<char>> pfloor_win;   // per condition, per band * W: the window's pressure likewise
  std::vector<std::vector<std::vector<int>>> counts;  // [replicate][heldout][cycle]
  // Where the time goes (seconds, summed over models).
  mutable double t_fit = 0, t_folds = 0, t_heldout = 0, t_floors = 0, t_bootstrap = 0;
};

double since(std::chrono::steady_clock::time_point& t) {
  const auto now = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(now - t).count();
  t = now;
  return s;
}

// The pressure chain's floor of every condition (for the report) and the cells it limits.
void mark_pressure_floors(Context& cx) {
  const BandDataset& data = *cx.data;
  cx.pressure_floors.clear();
  for (std::size_t k = 0; k < data.conditions.size(); ++k) cx.pressure_floors.push_back(pressure_floor(data, k));
  cx.pfloor_band = floor_limited_bands(data, &cx.pfloor_win);
}

std::vector<std::size_t> fold_train(const Context& cx, std::size_t heldout_index) {
  std::vector<std::size_t> t;
  for (std::size_t k : cx.train_fired)
    if (!cx.loo || k != cx.heldout[heldout_index]) t.push_back(k);
  t.insert(t.end(), cx.refs.begin(), cx.refs.end());
  return t;
}

// Microphone gains from training conditions: the channels standing out of the array's spread.
std::vector<double> estimate_mic_gains(const Context& cx, const std::vector<std::size_t>& conds) {
  const BandDataset& data = *cx.data;
  const std::size_t M = data.conditions.front().mics;
  std::vector<double> mean(M, 0.0);
  ExtendedModel none;
  int n = 0;
  for (std::size_t k : conds) {
    const ConditionData& d = data.conditions[k];
    if (d.mics != M) continue;
    const std::vector<double> off = mic_offsets(d, measured_side(d, none), cx.base_mask[k], nullptr);
    for (std::size_t m = 0; m < M; ++m) mean[m] += off[m];
    ++n;
  }
  for (double& x : mean) x /= std::max(1, n);
  const std::vector<double> t = mic_outliers(mean);
  const double med = median(mean);
  std::vector<double> g(M, 0.0);
  for (std::size_t m = 0; m < M; ++m)
    if (t[m] != 0.0) g[m] = mean[m] - med;
  return g;
}

struct Evaluated {
  ModelScore score;
  std::vector<ConditionPrediction> preds;   // per held-out condition
  std::vector<Measured> measured;           // per held-out condition
  std::vector<std::vector<double>> floors;  // per held-out condition: stationary floor per band
};

FitSetup base_setup(const Context& cx, const std::vector<BlockParam>& free) {
  FitSetup s;
  s.data = cx.data;
  s.train = cx.train_fired;
  s.train.insert(s.train.end(), cx.refs.begin(), cx.refs.end());
  s.free = free;
  s.fit_cycles = cx.opt->fit_cycles;
  return s;
}

// Stationary floor the model leaves on the training data, per band (per held-out fold: without that condition).
std::vector<std::vector<double>> stationary_floors(const Context& cx, const ExtendedModel& model) {
  const BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  std::vector<std::size_t> all = cx.train_fired;
  all.insert(all.end(), cx.refs.begin(), cx.refs.end());
  // Per training condition: mean excess per band and window (the exact prediction of the fit cycles: a band
  // factor for a second mode would misplace its energy between the windows).
  std::vector<std::vector<double>> excess(all.size(), std::vector<double>(nb * kW, 0.0));
  std::vector<std::vector<double>> predicted(all.size(), std::vector<double>(nb * kW, 0.0));
  for (std::size_t i = 0; i < all.size(); ++i) {
    const std::size_t k = all[i];
    const ConditionData& d = data.conditions[k];
    const Measured ms = measured_side(d, model);
    const ConditionPrediction pr = predict_condition(data, k, model, true, cx.opt->fit_cycles);
    const std::vector<double>& win = pr.win_ms;
    const std::size_t nc = pr.cycle_ms.size() / nb;
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t b = 0; b < nb; ++b)
        for (std::size_t w = 0; w < kW; ++w) {
          const double pred = win[(c * kW + w) * nb + b];
          excess[i][b * kW + w] += (ms.win[(c * kW + w) * nb + b] - pred) / static_cast<double>(nc);
          predicted[i][b * kW + w] += pred / static_cast<double>(nc);
        }
  }
  // The floor: the mean excess in the two windows where the model predicts least (averaged over conditions):
  // where the model makes (nearly) nothing, whatever is measured beyond it is stationary or locked noise there.
  std::vector<std::vector<double>> out(cx.heldout.size(), std::vector<double>(nb, 0.0));
  for (std::size_t h = 0; h < cx.heldout.size(); ++h)
    for (std::size_t b = 0; b < nb; ++b) {
      std::vector<std::pair<double, double>> win;  // (predicted, excess) per window
      for (std::size_t w = 0; w < kW; ++w) {
        double s = 0.0, q = 0.0;
        int n = 0;
        for (std::size_t i = 0; i < all.size(); ++i) {
          if (cx.loo && all[i] == cx.heldout[h]) continue;
          s += excess[i][b * kW + w];
          q += predicted[i][b * kW + w];
          ++n;
        }
        if (n > 0) win.emplace_back(q / n, s / n);
      }
      if (win.size() < 2) continue;
      std::sort(win.begin(), win.end());
      out[h][b] = std::max(0.0, 0.5 * (win[0].second + win[1].second));
    }
  return out;
}

Evaluated evaluate(const Context& cx, const CandidateSpec& spec, const ExtendedModel& start,
                   const std::vector<BlockParam>& base_free, bool is_baseline) {
  const BandDataset& data = *cx.data;
  const DiagnosisOptions& opt = *cx.opt;
  const std::size_t nb = data.band_count();
  Evaluated ev;
  ModelScore& sc = ev.score;
  sc.name = is_baseline ? "baseline" : spec.name;
  sc.effects = spec.effects;
  FitSetup setup = base_setup(cx, base_free);
  // Only the additive-noise extensions can explain bands the combustion-independent noise dominates.
  setup.scored = (spec.ext.stationary || spec.ext.locked) ? cx.base_mask : cx.tune_mask;
  setup.extensions = spec.ext;
  setup.extensions.mic_gain = false;
  for (BlockParam p : spec.extra_free)
    if (std::find(setup.free.begin(), setup.free.end(), p) == setup.free.end()) setup.free.push_back(p);
  ExtendedModel st = start;
  if (spec.ext.mic_gain) {
    st.on.mic_gain = true;
    st.ext.mic_gain_db = estimate_mic_gains(cx, setup.train);
  }
  for (BlockParam p : spec.extra_free)
    if (!(param_value(st.block, p) > 0)) set_param(st.block, p, 0.0);
  auto clk = std::chrono::steady_clock::now();
  const FitOutcome all = fit_model(setup, st);
  cx.t_fit += since(clk);
  sc.model = all.model;
  sc.parameters = all.parameters;
  if (spec.ext.mic_gain)
    for (double g : all.model.ext.mic_gain_db) sc.parameters += g != 0.0 ? 1 : 0;
  // Folds.
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    if (!cx.loo) {
      sc.fold_models.push_back(all.model);
      continue;
    }
    FitSetup f = setup;
    f.train = fold_train(cx, h);
    ExtendedModel fs = all.model;
    if (spec.ext.mic_gain) fs.ext.mic_gain_db = estimate_mic_gains(cx, f.train);
    sc.fold_models.push_back(refit_on_anchor(f, *all.anchor, fs).model);
  }
  cx.t_folds += since(clk);
  // Training figure (thesis metric over the fired training conditions, all-training fit, fit cycles).
  {
    double s = 0.0;
    int n = 0;
    for (std::size_t i = 0; i < all.anchor->conditions.size(); ++i) {
      const std::size_t k = all.anchor->conditions[i];
      if (std::find(cx.train_fired.begin(), cx.train_fired.end(), k) == cx.train_fired.end()) continue;
      const ConditionData& d = data.conditions[k];
      // The anchor sits at (or within the step tolerance of) the result: predicted = anchor with the factors.
      std::vector<double> pred = all.anchor->cycle_ms[i];
      apply_factors(extension_factors(data, k, all.anchor->spectra[i], all.anchor->block, all.model), d, pred, nullptr);
      const std::size_t nc = pred.size() / nb;
      double ms = 0.0;
      int nbands = 0;
      for (std::size_t b = 0; b < nb; ++b) {
        if (!cx.base_mask[k][b]) continue;
        double m = 0.0, p = 0.0;
        for (std::size_t c = 0; c < nc; ++c) {
          m += measured_ms(d, c, b, all.model);
          p += pred[c * nb + b];
        }
        if (m > 0 && p > 0) {
          ms += std::pow(db(m / p), 2);
          ++nbands;
        }
      }
      if (nbands > 0) {
        s += std::sqrt(ms / nbands);
        ++n;
      }
    }
    sc.train_rms_db = n > 0 ? s / n : kNaN;
  }
  // Held-out predictions (exact re-simulation at the fold's block, every cycle, crank windows).
  since(clk);
  ev.floors = stationary_floors(cx, all.model);
  cx.t_floors += since(clk);
  double thesis = 0.0;
  Parts sum;
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    const std::size_t k = cx.heldout[h];
    const ConditionData& d = data.conditions[k];
    ev.preds.push_back(predict_condition(data, k, sc.fold_models[h], true));
    ev.measured.push_back(measured_side(d, sc.fold_models[h]));
    ScoreDetail det;
    const Parts p = score_condition(d, ev.measured.back(), ev.preds.back(), cx.base_mask[k], cx.fast, ev.floors[h], nullptr, &det);
    sum.band_ms += p.band_ms;
    sum.mic += p.mic;
    sum.window_ms += p.window_ms;
    thesis += std::sqrt(p.band_ms);
    sc.gaps.push_back(det.gaps);
    sc.mic_resid.push_back(det.mic_resid);
    sc.window_gaps.push_back(det.window);
    sc.cell_gaps.push_back(det.cell);
    std::vector<double> att(nb, kNaN);
    const std::size_t nc = d.cycle_count();
    for (std::size_t b = 0; b < nb; ++b) {
      double cpl = 0.0, p2 = 0.0;
      for (std::size_t c = 0; c < nc; ++c) {
        cpl += d.cpl_ms[c * nb + b];
        p2 += ev.preds.back().cycle_ms[c * nb + b];
      }
      if (cpl > 0 && p2 > 0) att[b] = db(cpl / p2) - dsp::a_weighting_db(data.bands[b].exact_mid_hz);
    }
    sc.att_pred.push_back(att);
  }
  cx.t_heldout += since(clk);
  const double H = static_cast<double>(cx.heldout.size());
  sc.part_band_ms = sum.band_ms / H;
  sc.part_mic = sum.mic / H;
  sc.part_window_ms = sum.window_ms / H;
  sc.heldout_gap_db = std::sqrt(sum.total() / H);
  sc.heldout_thesis_rms_db = thesis / H;
  // Bootstrap replicates of the gap.
  for (const auto& rep : cx.counts) {
    double tot = 0.0;
    for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
      const std::size_t k = cx.heldout[h];
      tot += score_condition(data.conditions[k], ev.measured[h], ev.preds[h], cx.base_mask[k], cx.fast, ev.floors[h],
                             &rep[h], nullptr).total();
    }
    sc.replicate_gaps.push_back(std::sqrt(tot / H));
  }
  cx.t_bootstrap += since(clk);
  (void)opt;
  return ev;
}

void compare_with(ModelScore& m, const ModelScore& ref, double min_improvement) {
  m.improvement_db = ref.heldout_gap_db - m.heldout_gap_db;
  m.gap_closed_fraction = ref.heldout_gap_db > 0 ? 1.0 - m.heldout_gap_db / ref.heldout_gap_db : 0.0;
  std::vector<double> d;
  int wins = 0;
  for (std::size_t r = 0; r < m.replicate_gaps.size() && r < ref.replicate_gaps.size(); ++r) {
    d.push_back(ref.replicate_gaps[r] - m.replicate_gaps[r]);
    wins += m.replicate_gaps[r] < ref.replicate_gaps[r] ? 1 : 0;
  }
  std::sort(d.begin(), d.end());
  m.improvement_p05_db = d.empty() ? m.improvement_db : d[static_cast<std::size_t>(0.05 * static_cast<double>(d.size()))];
  m.win_fraction = d.empty() ? (m.improvement_db > 0 ? 1.0 : 0.0) : static_cast<double>(wins) / static_cast<double>(d.size());
  // No part of the composite gap may crown a model that makes the held-out thesis metric worse.
  m.thesis_worse = m.heldout_thesis_rms_db > ref.heldout_thesis_rms_db + kThesisWorseDb;
  m.significant = m.win_fraction >= 0.95 && m.improvement_db >= min_improvement && !m.thesis_worse;
  m.closes_band_db = std::sqrt(ref.part_band_ms) - std::sqrt(m.part_band_ms);
  m.closes_mic_db = std::sqrt(ref.part_mic) - std::sqrt(m.part_mic);
  m.closes_window_db = std::sqrt(ref.part_window_ms) - std::sqrt(m.part_window_ms);
}

// Share of replicates in which a beats b.
double beats(const ModelScore& a, const ModelScore& b) {
  int w = 0;
  const std::size_t n = std::min(a.replicate_gaps.size(), b.replicate_gaps.size());
  for (std::size_t r = 0; r < n; ++r) w += a.replicate_gaps[r] < b.replicate_gaps[r] ? 1 : 0;
  return n > 0 ? static_cast<double>(w) / static_cast<double>(n) : (a.heldout_gap_db < b.heldout_gap_db ? 1.0 : 0.0);
}

// Least-squares slope of y over x; pairs with an unknown (NaN) member are left out.
double linear_slope(const std::vector<double>& xs, const std::vector<double>& ys) {
  std::vector<double> x, y;
  for (std::size_t i = 0; i < xs.size() && i < ys.size(); ++i)
    if (std::isfinite(xs[i]) && std::isfinite(ys[i])) {
      x.push_back(xs[i]);
      y.push_back(ys[i]);
    }
  const std::size_t n = x.size();
  if (n < 2) return kNaN;
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n, my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxx > 0 ? sxy / sxx : kNaN;
}

// The floors in the report: per condition the pressure floor (stated or estimated) and the cells at a floor, per
// band the microphones' floor, and one summary line per group of conditions (the name before its first '_').
void report_floors(const Context& cx, const std::vector<double>& background_ms, Where& wh) {
  const BandDataset& data = *cx.data;
  const std::size_t K = data.conditions.size(), nb = data.band_count();
  constexpr double kBar = 1e5, kRef2 = 4e-10;
  auto level = [](double ms) { return ms > 0 ? 10.0 * std::log10(ms / kRef2) : kNaN; };
  struct Group { std::string name; int runs = 0, bands_min = 1 << 30, bands_max = 0, windows = 0, cells = 0; double from_hz = kNaN; };
  std::vector<Group> groups;
  for (std::size_t k = 0; k < K; ++k) {
    const ConditionData& d = data.conditions[k];
    const PressureFloor& f = cx.pressure_floors[k];
    const double enc = d.info.encoder_rate_hz;
    wh.pressure_floor_judged_by.push_back(f.density.empty() ? "none" : f.stated ? "stated" : "estimated");
    wh.pressure_floor_stated_bar.push_back(f.stated ? d.info.pressure_floor_pa / kBar : kNaN);
    wh.pressure_floor_estimated_bar.push_back(f.estimated_rms_per_sample_pa(enc) / kBar);
    wh.pressure_floor_estimated_grid_bar.push_back(f.estimated_rms_on_grid_pa(data) / kBar);
    std::vector<double> lv(nb, kNaN);
    for (std::size_t b = 0; b < nb && b < f.band_ms.size(); ++b) lv[b] = level(f.band_ms[b]);
    wh.pressure_floor_db.push_back(lv);
    int bands = 0, windows = 0;
    double from = kNaN;
    for (std::size_t b = 0; b < nb; ++b) {
      if (cx.floor_limited[k][b]) {
        ++bands;
        if (!std::isfinite(from) || data.bands[b].nominal_hz < from) from = data.bands[b].nominal_hz;
      }
      if (!cx.fast[b] || !cx.base_mask[k][b]) continue;
      for (std::size_t w = 0; w < kW; ++w) windows += cx.pfloor_win[k][b * kW + w] ? 1 : 0;
    }
    wh.floor_limited_bands.push_back(bands);
    wh.floor_limited_windows.push_back(windows);
    const std::string g = d.info.name.substr(0, d.info.name.find('_'));
    auto it = std::find_if(groups.begin(), groups.end(), [&](const Group& x) { return x.name == g; });
    if (it == groups.end()) it = groups.insert(groups.end(), Group{g});
    ++it->runs;
    it->bands_min = std::min(it->bands_min, bands);
    it->bands_max = std::max(it->bands_max, bands);
    it->windows += windows;
    for (std::size_t b = 0; b < nb; ++b) it->cells += cx.fast[b] && cx.base_mask[k][b] ? static_cast<int>(kW) : 0;
    if (std::isfinite(from) && !(it->from_hz <= from)) it->from_hz = from;
  }
  for (const Group& g : groups) {
    char line[256];
    const std::string range = g.bands_min == g.bands_max ? std::to_string(g.bands_min)
                                                        : std::to_string(g.bands_min) + "-" + std::to_string(g.bands_max);
    std::snprintf(line, sizeof line, "%s (%d run%s): %s of %zu bands floor-limited%s; %d of %d crank-window cells at the pressure floor",
                  g.name.c_str(), g.runs, g.runs == 1 ? "" : "s", range.c_str(), nb,
                  std::isfinite(g.from_hz) ? (" from " + std::to_string(static_cast<int>(g.from_hz)) + " Hz up").c_str() : "",
                  g.windows, g.windows + g.cells);
    wh.floor_summary.push_back(line);
  }
  wh.mic_floor_db.assign(nb, kNaN);
  const bool has_bg = std::any_of(background_ms.begin(), background_ms.end(), [](double x) { return x > 0; });
  wh.mic_floor_source = has_bg ? "background runs" : "quiet crank windows";
  std::vector<std::vector<double>> quiet;
  if (!has_bg)
    for (std::size_t k : cx.train_fired) quiet.push_back(quiet_window_mic_ms(data, k));
  for (std::size_t b = 0; b < nb; ++b) {
    std::vector<double> v;
    for (const auto& q : quiet)
      if (std::isfinite(q[b])) v.push_back(q[b]);
    wh.mic_floor_db[b] = level(has_bg ? background_ms[b] : median(v));
  }
}

}  // namespace

const std::vector<std::string>& candidate_effects() {
  static const std::vector<std::string> names{"cubic_damping",    "cubic_stiffness",  "second_mode",
                                              "mechanical_noise", "background_noise", "transducer_noise",
                                              "mic_gain",         "speed_dependence"};
  return names;
}

bool condition_matches(const std::string& pattern, const std::string& name) {
  if (pattern == name) return true;
  if (pattern.find('*') == std::string::npos) return name.rfind(pattern + "_", 0) == 0;
  // Glob with '*'.
  std::size_t p = 0, n = 0, star = std::string::npos, mark = 0;
  while (n < name.size()) {
    if (p < pattern.size() && (pattern[p] == name[n] || pattern[p] == '?')) {
      ++p;
      ++n;
    } else if (p < pattern.size() && pattern[p] == '*') {
      star = p++;
      mark = n;
    } else if (star != std::string::npos) {
      p = star + 1;
      n = ++mark;
    } else {
      return false;
    }
  }
  while (p < pattern.size() && pattern[p] == '*') ++p;
  return p == pattern.size();
}

DiagnosisResult diagnose(const BandDataset& data, const BlockParams& start, const std::string& model_name,
                         const DiagnosisOptions& opt) {
  using clock = std::chrono::steady_clock;
  const auto t_start = clock::now();
  auto t_stage = t_start;
  DiagnosisResult res;
  auto stage = [&](const std::string& name) {
    const auto now = clock::now();
    res.timing.emplace_back(name, std::chrono::duration<double>(now - t_stage).count());
    t_stage = now;
  };
  auto say = [&](const std::string& s) {
    if (opt.progress) opt.progress(s);
  };
  res.model_name = model_name;
  const std::size_t K = data.conditions.size(), nb = data.band_count();
  if (K == 0) throw std::invalid_argument("diagnose: no condition in the data");

  // ---------------------------------------------------------------- roles
  Context cx;
  cx.data = &data;
  cx.opt = &opt;
  auto matches_any = [](const std::vector<std::string>& pats, const std::string& name) {
    return std::any_of(pats.begin(), pats.end(), [&](const std::string& p) { return condition_matches(p, name); });
  };
  std::vector<std::size_t> fired, backgrounds;
  for (std::size_t k = 0; k < K; ++k) {
    const ConditionInfo& i = data.conditions[k].info;
    if (i.background) backgrounds.push_back(k);
    else if (i.motored) cx.refs.push_back(k);
    else fired.push_back(k);
  }
  for (const auto& pats : {opt.train, opt.holdout})
    for (const std::string& p : pats) {
      bool any = false;
      for (std::size_t k = 0; k < K; ++k) any = any || condition_matches(p, data.conditions[k].info.name);
      if (!any) throw std::invalid_argument("condition pattern '" + p + "' matches no condition in the data");
    }
  cx.loo = opt.holdout.empty();
  for (std::size_t k : fired) {
    const std::string& name = data.conditions[k].info.name;
    const bool held = !cx.loo && matches_any(opt.holdout, name);
    const bool trained = opt.train.empty() ? !held : matches_any(opt.train, name) && !held;
    if (held) cx.heldout.push_back(k);
    if (trained) cx.train_fired.push_back(k);
  }
  if (cx.loo) cx.heldout = cx.train_fired;
  if (cx.train_fired.empty()) throw std::invalid_argument("diagnose: no fired condition to train on");
  if (cx.heldout.empty()) throw std::invalid_argument("diagnose: no fired condition to hold out");
  if (cx.loo && cx.train_fired.size() < 2)
    throw std::invalid_argument("diagnose: leave-one-condition-out needs at least two fired conditions (or give --holdout)");
  res.heldout = cx.heldout;
  res.train = cx.train_fired;
  res.reference = cx.refs;
  res.leave_one_out = cx.loo;
  const std::vector<BlockParam> base_free = opt.free.empty() ? default_free_params(start) : opt.free;

  // ---------------------------------------------------------------- masks and floors
  say("bands and floors");
  const double margin = std::pow(10.0, opt.floor_margin_db / 10.0);
  auto mean_meas = [&](std::size_t k, std::size_t b) {
    const ConditionData& d = data.conditions[k];
    double s = 0.0;
    for (std::size_t c = 0; c < d.cycle_count(); ++c) s += d.mic_avg_ms(c, b);
    return s / static_cast<double>(d.cycle_count());
  };
  std::vector<double> bg(nb, 0.0);
  for (std::size_t k : backgrounds)
    for (std::size_t b = 0; b < nb; ++b) bg[b] += mean_meas(k, b) / static_cast<double>(backgrounds.size());
  // Combustion-independent excess of each motored run (start model).
  std::vector<std::vector<double>> excess(K);
  {
    ExtendedModel sm;
    sm.block = start;
    for (std::size_t k : cx.refs) {
      const ConditionPrediction p = predict_condition(data, k, sm, false);
      const std::size_t nc = data.conditions[k].cycle_count();
      excess[k].assign(nb, 0.0);
      for (std::size_t b = 0; b < nb; ++b) {
        double pr = 0.0;
        for (std::size_t c = 0; c < nc; ++c) pr += p.cycle_ms[c * nb + b] / static_cast<double>(nc);
        excess[k][b] = std::max(0.0, mean_meas(k, b) - pr);
      }
    }
  }
  auto nearest_ref = [&](std::size_t k) {
    std::size_t best = K;
    double bd = std::numeric_limits<double>::infinity();
    for (std::size_t r : cx.refs) {
      const double dd = std::abs(data.conditions[r].mean_speed_rpm() - data.conditions[k].mean_speed_rpm());
      if (dd < bd) {
        bd = dd;
        best = r;
      }
    }
    return best;
  };
  {
    std::vector<std::size_t> all = cx.train_fired;
    all.insert(all.end(), cx.heldout.begin(), cx.heldout.end());
    cx.fast = window_capable_bands(data, all);
  }
  mark_pressure_floors(cx);
  cx.base_mask.assign(K, std::vector<char>(nb, 0));
  cx.tune_mask.assign(K, std::vector<char>(nb, 0));
  cx.floor_limited.assign(K, std::vector<char>(nb, 0));
  cx.noise_dominated.assign(K, std::vector<char>(nb, 0));
  Where& wh = res.where;
  wh.band_notes.assign(nb, "");
  for (std::size_t b = 0; b < nb; ++b) {
    wh.band_hz.push_back(data.bands[b].nominal_hz);
    if (data.bands[b].nyquist_cut) wh.band_notes[b] = "nyquist_cut";
  }
  for (std::size_t k = 0; k < K; ++k) {
    const std::size_t r = nearest_ref(k);
    for (std::size_t b = 0; b < nb; ++b) {
      const double m = mean_meas(k, b);
      const bool ok = !data.bands[b].nyquist_cut && !data.band_line_free(k, b) && m > 0;
      // At a floor: the microphones within the margin of the background runs' level, or the pressure (so the
      // prediction) within the margin of the pressure chain's floor. Never fitted, never scored.
      const bool at_floor = (!backgrounds.empty() && m < bg[b] * margin) || cx.pfloor_band[k][b];
      cx.base_mask[k][b] = ok && !at_floor;
      cx.floor_limited[k][b] = ok && at_floor;
      // Dominated by the combustion-independent noise of the motored runs: scored (the additive candidates live
      // there), but the baseline is not tuned on it.
      const bool noisy = r < K && m < excess[r][b] * margin;
      cx.noise_dominated[k][b] = noisy;
      cx.tune_mask[k][b] = cx.base_mask[k][b] && !noisy;
      if (data.band_line_free(k, b) && wh.band_notes[b].empty()) wh.band_notes[b] = "line_free";
    }
  }
  // Bootstrap draws (the same for every model).
  {
    std::mt19937_64 rng(opt.seed);
    cx.counts.resize(static_cast<std::size_t>(std::max(0, opt.bootstrap)));
    for (auto& rep : cx.counts) {
      rep.resize(cx.heldout.size());
      for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
        const std::size_t nc = data.conditions[cx.heldout[h]].cycle_count();
        rep[h].assign(nc, 0);
        std::uniform_int_distribution<std::size_t> pick(0, nc - 1);
        for (std::size_t i = 0; i < nc; ++i) ++rep[h][pick(rng)];
      }
    }
  }
  stage("bands and floors");

  // ---------------------------------------------------------------- baseline
  say("baseline: tuning " + model_name + " on " + std::to_string(cx.train_fired.size()) + " fired and " +
      std::to_string(cx.refs.size()) + " motored condition(s)");
  ExtendedModel start_model;
  start_model.block = start;
  Evaluated base = evaluate(cx, CandidateSpec{}, start_model, base_free, true);
  res.baseline = base.score;
  stage("baseline");

  // ---------------------------------------------------------------- candidates
  const std::vector<std::string> names = opt.candidates.empty() ? candidate_effects() : opt.candidates;
  std::vector<CandidateSpec> specs;
  std::vector<Evaluated> evals;
  for (const std::string& n : names) {
    say("candidate " + n);
    specs.push_back(spec_for(n));
    // Cubic coefficients change the waveform: their fit starts from the given model, not from a linear block
    // already bent to imitate them.
    const bool cubic = !specs.back().extra_free.empty();
    Evaluated e = evaluate(cx, specs.back(), cubic ? start_model : base.score.model, base_free, false);
    compare_with(e.score, res.baseline, opt.min_improvement_db);
    evals.push_back(std::move(e));
    stage("candidate " + n);
  }
  // Rank: held-out gap; a simpler candidate first when the better one does not beat it in 95 % of replicates by at
  // least min_improvement_db (the same bar a candidate must clear against the baseline).
  std::vector<std::size_t> order(evals.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return evals[a].score.heldout_gap_db < evals[b].score.heldout_gap_db;
  });
  for (std::size_t pass = 0; pass < order.size(); ++pass)
    for (std::size_t i = 0; i + 1 < order.size(); ++i) {
      const ModelScore& a = evals[order[i]].score;
      const ModelScore& b = evals[order[i + 1]].score;
      const bool clearly_better = beats(a, b) >= 0.95 && b.heldout_gap_db - a.heldout_gap_db >= opt.min_improvement_db;
      if (b.parameters < a.parameters && b.significant && !clearly_better) std::swap(order[i], order[i + 1]);
    }
  for (std::size_t i : order) res.candidates.push_back(evals[i].score);

  // ---------------------------------------------------------------- verdict
  Verdict& v = res.verdict;
  v.heldout_rms_before_db = res.baseline.heldout_gap_db;
  v.heldout_thesis_before_db = res.baseline.heldout_thesis_rms_db;
  {
    double m = 0.0, s = 0.0;
    const auto& r = res.baseline.replicate_gaps;
    for (double x : r) m += x;
    m /= std::max<std::size_t>(1, r.size());
    for (double x : r) s += (x - m) * (x - m);
    v.noise_db = r.size() > 1 ? std::sqrt(s / static_cast<double>(r.size() - 1)) : 0.0;
  }
  std::vector<std::size_t> sig;
  for (std::size_t i : order)
    if (evals[i].score.significant) sig.push_back(i);
  const ModelScore* selected = nullptr;
  std::string candidate_partner;  // the second effect kept with the verdict's
  if (v.heldout_rms_before_db <= opt.tolerance_db || v.heldout_rms_before_db <= 2.0 * v.noise_db) {
    v.effect = "none";
    v.explanation = "the tuned baseline already agrees with the held-out conditions within the tolerance (" +
                    std::to_string(opt.tolerance_db).substr(0, 4) + " dB) and the cycle-to-cycle noise";
  } else if (sig.empty()) {
    v.effect = "unexplained";
    v.explanation = "a significant gap remains and no candidate effect reduces it significantly";
  } else {
    const ModelScore& best = evals[sig[0]].score;
    selected = &best;
    v.effect = best.name;
    if (order.size() > 1 && best.heldout_gap_db > opt.tolerance_db) {
      // A second effect on top of the best: tried with every other candidate, significant alone or not (one
      // effect can hide another: a cubic spring's detuning under a cubic damper's flattening). When the
      // runner-up is significant and close (within kCloseRunnerUp of the best's gap) and no pair with the best
      // closes the gap to the tolerance, the order of the two is not clear: pairs are started from the runner-up
      // too. The best pair is kept when it beats the best single in 95 % of the replicates by at least
      // kPairShare of its gap (and min_improvement_db), so that a free term riding along for a few hundredths of
      // a dB is not named; of its two effects the one better alone is the verdict, the other its partner.
      constexpr std::size_t npos = static_cast<std::size_t>(-1);
      std::size_t best_pair = npos;
      auto pairs_from = [&](std::size_t first, const std::vector<std::size_t>& skip) {
        for (std::size_t i : order) {
          if (i == first || std::find(skip.begin(), skip.end(), i) != skip.end()) continue;
          say("combination " + evals[first].score.name + " + " + evals[i].score.name);
          Evaluated e = evaluate(cx, combine(specs[first], specs[i]), evals[first].score.model, base_free, false);
          compare_with(e.score, res.baseline, opt.min_improvement_db);
          res.combinations.push_back(e.score);
          if (best_pair == npos || e.score.heldout_gap_db < res.combinations[best_pair].heldout_gap_db)
            best_pair = res.combinations.size() - 1;
        }
      };
      pairs_from(sig[0], {});
      if (sig.size() > 1 && best_pair != npos && res.combinations[best_pair].heldout_gap_db > opt.tolerance_db &&
          evals[sig[1]].score.heldout_gap_db <= kCloseRunnerUp * best.heldout_gap_db)
        pairs_from(sig[1], {sig[0]});
      stage("combinations");
      bool keep = false;
      if (best_pair != npos) {
        const ModelScore& pair = res.combinations[best_pair];
        const double gain = best.heldout_gap_db - pair.heldout_gap_db;
        keep = !pair.thesis_worse && beats(pair, best) >= 0.95 &&
               gain >= std::max(opt.min_improvement_db, kPairShare * best.heldout_gap_db);
      }
      // Best first, for the report: the pair with the smallest gap (best_pair) comes to the front.
      std::stable_sort(res.combinations.begin(), res.combinations.end(),
                       [](const ModelScore& a, const ModelScore& b) { return a.heldout_gap_db < b.heldout_gap_db; });
      if (keep) {
        selected = &res.combinations.front();
        // The effect better alone is named first.
        auto alone = [&](const std::string& name) {
          for (const Evaluated& e : evals)
            if (e.score.name == name) return e.score.heldout_gap_db;
          return std::numeric_limits<double>::infinity();
        };
        std::string first = selected->effects.front(), second = selected->effects.back();
        if (alone(second) < alone(first)) std::swap(first, second);
        v.effect = first;
        v.also.push_back(second);
      }
      candidate_partner = keep ? v.also.front() : std::string();
    }
    const double closed = 1.0 - selected->heldout_gap_db / v.heldout_rms_before_db;
    // Unexplained: a significant gap remains. What the best leaves within the tolerance is no such gap, however
    // small a share of a gap barely above the tolerance it closed.
    if (closed < opt.min_closed_fraction && selected->heldout_gap_db > opt.tolerance_db) {
      const std::string best_name = v.effect;
      v.effect = "unexplained";
      v.also.clear();
      v.explanation = "a significant gap remains: the best candidate (" + best_name + ") closes only " +
                      std::to_string(static_cast<int>(std::lround(100 * closed))) + " % of it";
    } else {
      v.explanation = v.effect + " closes " + std::to_string(static_cast<int>(std::lround(100 * closed))) +
                      " % of the held-out gap";
      if (!v.also.empty()) v.explanation += " together with " + v.also.front();
    }
  }
  for (ModelScore& c : res.candidates)
    if (!candidate_partner.empty() && !v.also.empty() && c.name == candidate_partner) c.significant_on_top = true;
  const ModelScore& after = (selected && v.effect != "unexplained" && v.effect != "none") ? *selected : res.baseline;
  v.heldout_rms_after_db = after.heldout_gap_db;
  v.heldout_thesis_after_db = after.heldout_thesis_rms_db;
  v.gap_closed_fraction = v.heldout_rms_before_db > 0 ? 1.0 - v.heldout_rms_after_db / v.heldout_rms_before_db : 0.0;
  auto per_band_rms = [&](const ModelScore& m) {
    std::vector<double> out(nb, kNaN);
    for (std::size_t b = 0; b < nb; ++b) {
      double s = 0.0;
      int n = 0;
      for (const auto& g : m.gaps)
        if (std::isfinite(g[b])) {
          s += g[b] * g[b];
          ++n;
        }
      if (n > 0) out[b] = std::sqrt(s / n);
    }
    return out;
  };
  v.band_before_db = per_band_rms(res.baseline);
  v.band_after_db = per_band_rms(after);

  // ---------------------------------------------------------------- where
  for (std::size_t k = 0; k < K; ++k) {
    const ConditionData& d = data.conditions[k];
    wh.conditions.push_back(d.info.name);
    const bool t = std::find(cx.train_fired.begin(), cx.train_fired.end(), k) != cx.train_fired.end();
    const bool h = std::find(cx.heldout.begin(), cx.heldout.end(), k) != cx.heldout.end();
    std::string role = d.info.background ? "floor" : d.info.motored ? "reference" : t && h ? "train+heldout" : t ? "train" : h ? "heldout" : "unused";
    wh.roles.push_back(role);
  }
  wh.scored = cx.base_mask;
  wh.floor_limited = cx.floor_limited;
  wh.noise_dominated = cx.noise_dominated;
  report_floors(cx, bg, wh);
  wh.floor_db.assign(nb, kNaN);
  wh.background_db.assign(nb, kNaN);
  for (std::size_t b = 0; b < nb; ++b) {
    double s = 0.0;
    int n = 0;
    for (std::size_t r : cx.refs) {
      s += excess[r][b];
      ++n;
    }
    if (n > 0 && s > 0) wh.floor_db[b] = 10.0 * std::log10(s / n / 4e-10);
    if (!backgrounds.empty() && bg[b] > 0) wh.background_db[b] = 10.0 * std::log10(bg[b] / 4e-10);
  }
  wh.gap = res.baseline.gaps;
  wh.gap_per_band_rms = v.band_before_db;
  std::vector<double> speeds, sois, loads, cycle_x, cycle_y;
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    const std::size_t k = cx.heldout[h];
    const ConditionData& d = data.conditions[k];
    const std::size_t nc = d.cycle_count();
    wh.gap_per_condition_rms.push_back(rms_db(res.baseline.gaps[h]));
    double mg = 0.0;
    int n = 0;
    for (double g : res.baseline.gaps[h])
      if (std::isfinite(g)) {
        mg += g;
        ++n;
      }
    wh.mean_gap_db.push_back(n > 0 ? mg / n : kNaN);
    double cpl = 0.0;
    std::vector<double> att_m(nb, kNaN), cpl_b(nb, kNaN);
    for (std::size_t b = 0; b < nb; ++b) {
      double c = 0.0, m = 0.0;
      for (std::size_t cy = 0; cy < nc; ++cy) {
        c += d.cpl_ms[cy * nb + b];
        m += d.mic_avg_ms(cy, b);
      }
      if (!data.bands[b].nyquist_cut) cpl += c / nc;
      if (c > 0 && m > 0) att_m[b] = db(c / m) - dsp::a_weighting_db(data.bands[b].exact_mid_hz);
      if (c > 0) cpl_b[b] = 10.0 * std::log10(c / nc / 4e-10);
    }
    wh.cpl_overall_db.push_back(10.0 * std::log10(cpl / 4e-10));
    wh.att_meas.push_back(att_m);
    wh.cpl_db.push_back(cpl_b);
    speeds.push_back(d.mean_speed_rpm() / 1000.0);
    sois.push_back(d.info.soi_deg_btdc);
    loads.push_back(d.info.load_nm);
    // Per-cycle: mean gap over the scored bands vs the cycle's overall CPL, deviations from the condition mean.
    std::vector<double> xs, ys;
    const ConditionPrediction& p = base.preds[h];
    for (std::size_t cy = 0; cy < nc; ++cy) {
      double g = 0.0, c = 0.0;
      int nn = 0;
      for (std::size_t b = 0; b < nb; ++b) {
        if (!data.bands[b].nyquist_cut) c += d.cpl_ms[cy * nb + b];
        if (!cx.base_mask[k][b]) continue;
        const double m = d.mic_avg_ms(cy, b), q = p.cycle_ms[cy * nb + b];
        if (m > 0 && q > 0) {
          g += db(m / q);
          ++nn;
        }
      }
      if (nn == 0 || !(c > 0)) continue;
      xs.push_back(10.0 * std::log10(c));
      ys.push_back(g / nn);
    }
    const double mx = xs.empty() ? 0 : std::accumulate(xs.begin(), xs.end(), 0.0) / xs.size();
    const double my = ys.empty() ? 0 : std::accumulate(ys.begin(), ys.end(), 0.0) / ys.size();
    for (std::size_t i = 0; i < xs.size(); ++i) {
      cycle_x.push_back(xs[i] - mx);
      cycle_y.push_back(ys[i] - my);
    }
  }
  wh.att_base = res.baseline.att_pred;
  wh.amplitude_slope_db_per_db = linear_slope(wh.cpl_overall_db, wh.mean_gap_db);
  wh.cycle_amplitude_slope_db_per_db = linear_slope(cycle_x, cycle_y);
  wh.speed_slope_db_per_krpm = linear_slope(speeds, wh.mean_gap_db);
  wh.soi_slope_db_per_deg = linear_slope(sois, wh.mean_gap_db);
  wh.load_slope_db_per_nm = linear_slope(loads, wh.mean_gap_db);
  {
    const std::size_t M = data.conditions[cx.heldout.front()].mics;
    wh.mic_offset_db.assign(M, 0.0);
    wh.mic_gap_rms_db.assign(M, 0.0);
    for (std::size_t m = 0; m < M; ++m) wh.mics.push_back("mic" + std::to_string(m + 1));
    ExtendedModel none;
    for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
      const std::size_t k = cx.heldout[h];
      const ConditionData& d = data.conditions[k];
      const Measured ms = measured_side(d, none);
      const std::vector<double> off = mic_offsets(d, ms, cx.base_mask[k], nullptr);
      const std::size_t nc = d.cycle_count();
      for (std::size_t m = 0; m < M && m < d.mics; ++m) {
        wh.mic_offset_db[m] += off[m] / static_cast<double>(cx.heldout.size());
        std::vector<double> g(nb, kNaN);
        for (std::size_t b = 0; b < nb; ++b) {
          if (!cx.base_mask[k][b]) continue;
          double a = 0.0, q = 0.0;
          for (std::size_t cy = 0; cy < nc; ++cy) {
            a += d.mic_ms[(cy * d.mics + m) * nb + b];
            q += base.preds[h].cycle_ms[cy * nb + b];
          }
          if (a > 0 && q > 0) g[b] = db(a / q);
        }
        wh.mic_gap_rms_db[m] += rms_db(g) / static_cast<double>(cx.heldout.size());
      }
    }
  }
  wh.window_gap_db.assign(kW, 0.0);
  for (std::size_t w = 0; w < kW; ++w) {
    wh.window_start_deg.push_back(-360.0 + 720.0 * static_cast<double>(w) / kW);
    double s = 0.0;
    int n = 0;
    for (const auto& g : res.baseline.window_gaps)
      if (std::isfinite(g[w])) {
        s += g[w];
        ++n;
      }
    wh.window_gap_db[w] = n > 0 ? s / n : kNaN;
    std::vector<double> per_band(nb, kNaN);
    for (std::size_t b = 0; b < nb; ++b) {
      double sb = 0.0;
      int nn = 0;
      for (const auto& g : res.baseline.cell_gaps)
        if (std::isfinite(g[w * nb + b])) sb += g[w * nb + b], ++nn;
      if (nn > 0) per_band[b] = sb / nn;
    }
    wh.window_band_gap_db.push_back(per_band);
  }
  wh.coherent_fraction.assign(nb, 0.0);
  wh.fluct_coherence.assign(nb, 0.0);
  wh.periodic_share.assign(nb, 0.0);
  for (std::size_t b = 0; b < nb; ++b) {
    double a = 0.0, f = 0.0, p = 0.0;
    int n = 0;
    for (std::size_t k : fired) {
      const ConditionData& d = data.conditions[k];
      if (!std::isfinite(d.coherent_fraction[b])) continue;
      a += d.coherent_fraction[b];
      f += d.fluct_coherence[b];
      p += d.periodic_share[b];
      ++n;
    }
    wh.coherent_fraction[b] = n > 0 ? a / n : kNaN;
    wh.fluct_coherence[b] = n > 0 ? f / n : kNaN;
    wh.periodic_share[b] = n > 0 ? p / n : kNaN;
  }
  stage("report figures");
  res.timing.emplace_back("(of which) fits on all training conditions", cx.t_fit);
  res.timing.emplace_back("(of which) fold refits", cx.t_folds);
  res.timing.emplace_back("(of which) held-out re-simulation and scoring", cx.t_heldout);
  res.timing.emplace_back("(of which) stationary floors (training re-simulation)", cx.t_floors);
  res.timing.emplace_back("(of which) bootstrap", cx.t_bootstrap);
  res.seconds = std::chrono::duration<double>(clock::now() - t_start).count();
  return res;
}

}  // namespace noisemon::model
