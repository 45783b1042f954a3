// One model of the diagnosis, the baseline or a candidate, evaluated: tuned on all training conditions, refitted
// on every leave-one-condition-out fold (a surrogate solve on the all-training anchor), re-simulated exactly on
// the held-out conditions and scored there (gap.cpp), with the gap's bootstrap replicates.
#include <algorithm>
#include <chrono>
#include <cmath>

#include "dsp/weighting.hpp"
#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

double since(std::chrono::steady_clock::time_point& t) {
  const auto now = std::chrono::steady_clock::now();
  const double s = std::chrono::duration<double>(now - t).count();
  t = now;
  return s;
}

bool contains(const std::vector<std::size_t>& v, std::size_t k) { return std::find(v.begin(), v.end(), k) != v.end(); }

// The model refitted without the held-out conditions `left_out` (indices into cx.heldout; leave-one-out folds only):
// the fired training conditions but those, and the references, in a surrogate solve on the all-training anchor.
fit::ExtendedModel refit_without(const Context& cx, const CandidateSpec& spec, const fit::FitSetup& setup,
                                 const fit::FitOutcome& all, const std::vector<std::size_t>& left_out) {
  fit::FitSetup f = setup;
  f.train.clear();
  for (std::size_t k : cx.train_fired)
    if (std::none_of(left_out.begin(), left_out.end(), [&](std::size_t h) { return cx.heldout[h] == k; }))
      f.train.push_back(k);
  f.train.insert(f.train.end(), cx.refs.begin(), cx.refs.end());
  fit::ExtendedModel start = all.model;
  if (spec.ext.mic_gain) start.ext.mic_gain_db = estimate_mic_gains(cx, f.train);
  return fit::refit_on_anchor(f, *all.anchor, start).model;
}

// The fit on all training conditions: the spec's extensions and free parameters on the baseline's.
fit::FitSetup candidate_setup(const Context& cx, const CandidateSpec& spec,
                              const std::vector<fit::BlockParam>& base_free) {
  fit::FitSetup s;
  s.data = cx.data;
  s.train = cx.train_fired;
  s.train.insert(s.train.end(), cx.refs.begin(), cx.refs.end());
  s.free = base_free;
  s.fit_cycles = cx.opt->fit_cycles;
  // The baseline tunes only where combustion noise dominates: the block must not bend to fit noise it cannot make.
  // A candidate is fitted on every scored band, motored runs included: what the motored runs hear beyond the start
  // model may be its own doing (a panel the motored pressure drives too), and the joint fit over fired and motored
  // runs is what tells a pressure-driven effect from an additive one.
  s.scored = spec.effects.empty() ? cx.tune_mask : cx.base_mask;
  s.extensions = spec.ext;
  s.extensions.mic_gain = false;
  for (fit::BlockParam p : spec.extra_free)
    if (std::find(s.free.begin(), s.free.end(), p) == s.free.end()) s.free.push_back(p);
  return s;
}

fit::ExtendedModel candidate_start(const Context& cx, const CandidateSpec& spec, const fit::ExtendedModel& start,
                                   const std::vector<std::size_t>& train) {
  fit::ExtendedModel st = start;
  if (spec.ext.mic_gain) {
    st.on.mic_gain = true;
    st.ext.mic_gain_db = estimate_mic_gains(cx, train);
  }
  for (fit::BlockParam p : spec.extra_free)
    if (!(param_value(st.block, p) > 0)) set_param(st.block, p, 0.0);
  return st;
}

std::vector<fit::ExtendedModel> fold_models(const Context& cx, const CandidateSpec& spec, const fit::FitSetup& setup,
                                            const fit::FitOutcome& all) {
  std::vector<fit::ExtendedModel> folds;
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    folds.push_back(cx.loo ? refit_without(cx, spec, setup, all, {h}) : all.model);
  }
  return folds;
}

// Thesis metric over the fired training conditions: the all-training fit on its fit cycles.
double training_rms(const Context& cx, const fit::FitOutcome& all) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  double s = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < all.anchor->conditions.size(); ++i) {
    const std::size_t k = all.anchor->conditions[i];
    if (!contains(cx.train_fired, k)) continue;
    const fit::ConditionData& d = data.conditions[k];
    // The anchor sits at (or within the step tolerance of) the result: predicted = anchor with the factors.
    std::vector<double> pred = all.anchor->cycle_ms[i];
    fit::apply_factors(fit::extension_factors(data, k, all.anchor->spectra[i], all.anchor->block, all.model), d, pred,
                       nullptr);
    const std::size_t nc = pred.size() / nb;
    double ms = 0.0;
    int nbands = 0;
    for (std::size_t b = 0; b < nb; ++b) {
      if (!cx.base_mask[k][b]) continue;
      double m = 0.0, p = 0.0;
      for (std::size_t c = 0; c < nc; ++c) {
        m += fit::measured_ms(d, c, b, all.model);
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
  return n > 0 ? s / n : kNaN;
}

// Predicted attenuation CPL - SPL_A per band of a condition, dB.
std::vector<double> predicted_attenuation(const fit::BandDataset& data, const fit::ConditionData& d,
                                          const fit::ConditionPrediction& pred) {
  const std::size_t nb = data.band_count(), nc = d.cycle_count();
  std::vector<double> att(nb, kNaN);
  for (std::size_t b = 0; b < nb; ++b) {
    double cpl = 0.0, p2 = 0.0;
    for (std::size_t c = 0; c < nc; ++c) {
      cpl += d.cpl_ms[c * nb + b];
      p2 += pred.cycle_ms[c * nb + b];
    }
    if (cpl > 0 && p2 > 0) att[b] = db(cpl / p2) - dsp::a_weighting_db(data.bands[b].exact_mid_hz);
  }
  return att;
}

// Every held-out condition re-simulated at its fold's model and scored; the sums of the parts over them and of
// the thesis metric in *thesis.
Parts score_heldout(const Context& cx, Evaluated& ev, double* thesis) {
  const fit::BandDataset& data = *cx.data;
  ModelScore& sc = ev.score;
  Parts sum;
  for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
    const std::size_t k = cx.heldout[h];
    const fit::ConditionData& d = data.conditions[k];
    ev.preds.push_back(fit::predict_condition(data, k, sc.fold_models[h], true));
    ev.measured.push_back(measured_side(d, sc.fold_models[h]));
    ScoreDetail det;
    const Parts p =
        score_condition(d, ev.measured.back(), ev.preds.back(), cx.base_mask[k], cx.fast, ev.floors[h], nullptr, &det);
    sum.band_ms += p.band_ms;
    sum.mic += p.mic;
    sum.window_ms += p.window_ms;
    *thesis += std::sqrt(p.band_ms);
    sc.gaps.push_back(det.gaps);
    sc.mic_resid.push_back(det.mic_resid);
    sc.window_gaps.push_back(det.window);
    sc.cell_gaps.push_back(det.cell);
    sc.att_pred.push_back(predicted_attenuation(data, d, ev.preds.back()));
  }
  return sum;
}

// The held-out gap of every bootstrap replicate (the cycles each draw picked, the same predictions).
std::vector<double> replicate_gaps(const Context& cx, const Evaluated& ev) {
  const fit::BandDataset& data = *cx.data;
  const double H = static_cast<double>(cx.heldout.size());
  std::vector<double> gaps;
  for (const auto& rep : cx.counts) {
    double tot = 0.0;
    for (std::size_t h = 0; h < cx.heldout.size(); ++h) {
      const std::size_t k = cx.heldout[h];
      tot += score_condition(data.conditions[k], ev.measured[h], ev.preds[h], cx.base_mask[k], cx.fast, ev.floors[h],
                             &rep[h], nullptr)
                 .total();
    }
    gaps.push_back(std::sqrt(tot / H));
  }
  return gaps;
}

// Leave-one-group-out: per speed group (Context::groups), the model refitted without the group's fired conditions
// (like the condition folds), each of them re-simulated and scored;
// the gap over all of them, NaN without groups. A flexible candidate that fits what is peculiar to one operating
// point cannot carry it to another.
double group_gap(const Context& cx, const CandidateSpec& spec, const fit::FitSetup& setup, const fit::FitOutcome& all,
                 const Evaluated& ev) {
  if (cx.groups.empty()) return kNaN;
  const fit::BandDataset& data = *cx.data;
  double total = 0.0;
  int scored = 0;
  for (const std::vector<std::size_t>& group : cx.groups) {
    const fit::ExtendedModel model = refit_without(cx, spec, setup, all, group);
    for (std::size_t h : group) {
      const std::size_t k = cx.heldout[h];
      const fit::ConditionData& d = data.conditions[k];
      total += score_condition(d, measured_side(d, model), fit::predict_condition(data, k, model, true),
                               cx.base_mask[k], cx.fast, ev.floors[h], nullptr, nullptr)
                   .total();
      ++scored;
    }
  }
  return scored > 0 ? std::sqrt(total / scored) : kNaN;
}

}  // namespace

std::vector<double> estimate_mic_gains(const Context& cx, const std::vector<std::size_t>& conds) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t M = data.conditions.front().mics;
  std::vector<double> mean(M, 0.0);
  fit::ExtendedModel none;
  int n = 0;
  for (std::size_t k : conds) {
    const fit::ConditionData& d = data.conditions[k];
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

std::vector<std::vector<double>> stationary_floors(const Context& cx, const fit::ExtendedModel& model) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  std::vector<std::size_t> all = cx.train_fired;
  all.insert(all.end(), cx.refs.begin(), cx.refs.end());
  // Per training condition: mean excess per band and window (the exact prediction of the fit cycles: a band
  // factor for a second mode would misplace its energy between the windows).
  std::vector<std::vector<double>> excess(all.size(), std::vector<double>(nb * kW, 0.0));
  std::vector<std::vector<double>> predicted(all.size(), std::vector<double>(nb * kW, 0.0));
  for (std::size_t i = 0; i < all.size(); ++i) {
    const fit::ConditionData& d = data.conditions[all[i]];
    const Measured ms = measured_side(d, model);
    const fit::ConditionPrediction pr = predict_condition(data, all[i], model, true, cx.opt->fit_cycles);
    const std::size_t nc = pr.cycle_ms.size() / nb;
    for (std::size_t c = 0; c < nc; ++c)
      for (std::size_t b = 0; b < nb; ++b)
        for (std::size_t w = 0; w < kW; ++w) {
          const double pred = pr.win_ms[(c * kW + w) * nb + b];
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

Evaluated evaluate(const Context& cx, const CandidateSpec& spec, const fit::ExtendedModel& start,
                   const std::vector<fit::BlockParam>& base_free, bool is_baseline) {
  Evaluated ev;
  ModelScore& sc = ev.score;
  sc.name = is_baseline ? "baseline" : spec.name;
  sc.effects = spec.effects;
  const fit::FitSetup setup = candidate_setup(cx, spec, base_free);
  const fit::ExtendedModel st = candidate_start(cx, spec, start, setup.train);
  auto clk = std::chrono::steady_clock::now();
  const fit::FitOutcome all = fit_model(setup, st);
  cx.t_fit += since(clk);
  sc.model = all.model;
  sc.parameters = all.parameters;
  if (spec.ext.mic_gain)
    for (double g : all.model.ext.mic_gain_db) sc.parameters += g != 0.0 ? 1 : 0;
  sc.fold_models = fold_models(cx, spec, setup, all);
  cx.t_folds += since(clk);
  sc.train_rms_db = training_rms(cx, all);
  judge_motored_law(cx, sc);
  // Held-out predictions (exact re-simulation at the fold's block, every cycle, crank windows).
  since(clk);
  ev.floors = stationary_floors(cx, all.model);
  cx.t_floors += since(clk);
  double thesis = 0.0;
  const Parts sum = score_heldout(cx, ev, &thesis);
  cx.t_heldout += since(clk);
  const double H = static_cast<double>(cx.heldout.size());
  sc.part_band_ms = sum.band_ms / H;
  sc.part_mic = sum.mic / H;
  sc.part_window_ms = sum.window_ms / H;
  sc.heldout_gap_db = std::sqrt(sum.total() / H);
  sc.heldout_thesis_rms_db = thesis / H;
  set_information_criterion(sc);
  sc.heldout_group_gap_db = group_gap(cx, spec, setup, all, ev);
  cx.t_groups += since(clk);
  sc.replicate_gaps = replicate_gaps(cx, ev);
  cx.t_bootstrap += since(clk);
  return ev;
}

}  // namespace noisemon::model::diagnosis
