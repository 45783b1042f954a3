// The first stage of the band diagnosis: the part every condition plays (fired conditions are trained on and
// scored, motored runs are references, background runs the microphones' floor) and the cells no model is fitted
// or scored on (Nyquist-cut and line-free bands, cells at the pressure chain's or the background runs' floor), or
// the baseline is not tuned on (dominated by the motored runs' combustion-independent noise).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

bool matches_any(const std::vector<std::string>& patterns, const std::string& name) {
  return std::any_of(patterns.begin(), patterns.end(),
                     [&](const std::string& p) { return condition_matches(p, name); });
}

void check_patterns_match(const fit::BandDataset& data, const DiagnosisOptions& opt) {
  for (const auto& pats : {opt.train, opt.holdout})
    for (const std::string& p : pats) {
      bool any = false;
      for (std::size_t k = 0; k < data.conditions.size(); ++k)
        any = any || condition_matches(p, data.conditions[k].info.name);
      if (!any) throw std::invalid_argument("condition pattern '" + p + "' matches no condition in the data");
    }
}

// Cycle-mean microphone-average mean square of a condition in a band.
double mean_meas(const fit::BandDataset& data, std::size_t k, std::size_t b) {
  const fit::ConditionData& d = data.conditions[k];
  double s = 0.0;
  for (std::size_t c = 0; c < d.cycle_count(); ++c) s += d.mic_avg_ms(c, b);
  return s / static_cast<double>(d.cycle_count());
}

// Per band: the background runs' mean level (0 without background runs).
std::vector<double> background_levels(const fit::BandDataset& data, const std::vector<std::size_t>& backgrounds) {
  std::vector<double> bg(data.band_count(), 0.0);
  for (std::size_t k : backgrounds)
    for (std::size_t b = 0; b < bg.size(); ++b)
      bg[b] += mean_meas(data, k, b) / static_cast<double>(backgrounds.size());
  return bg;
}

// Combustion-independent excess of each motored run over the start model (empty for the other conditions).
std::vector<std::vector<double>> motored_excess(const fit::BandDataset& data, const std::vector<std::size_t>& refs,
                                                const BlockParams& start) {
  const std::size_t nb = data.band_count();
  std::vector<std::vector<double>> excess(data.conditions.size());
  fit::ExtendedModel sm;
  sm.block = start;
  for (std::size_t k : refs) {
    const fit::ConditionPrediction p = predict_condition(data, k, sm, false);
    const std::size_t nc = data.conditions[k].cycle_count();
    excess[k].assign(nb, 0.0);
    for (std::size_t b = 0; b < nb; ++b) {
      double pr = 0.0;
      for (std::size_t c = 0; c < nc; ++c) pr += p.cycle_ms[c * nb + b] / static_cast<double>(nc);
      excess[k][b] = std::max(0.0, mean_meas(data, k, b) - pr);
    }
  }
  return excess;
}

// The motored run nearest in speed to condition k (the number of conditions when there is none).
std::size_t nearest_ref(const fit::BandDataset& data, const std::vector<std::size_t>& refs, std::size_t k) {
  std::size_t best = data.conditions.size();
  double bd = std::numeric_limits<double>::infinity();
  for (std::size_t r : refs) {
    const double dd = std::abs(data.conditions[r].mean_speed_rpm() - data.conditions[k].mean_speed_rpm());
    if (dd < bd) {
      bd = dd;
      best = r;
    }
  }
  return best;
}

// Dominated by the combustion-independent noise of the motored run r (the nearest in speed): scored (the additive
// candidates live there), but the baseline is not tuned on it. m: the cell's cycle-mean level.
void mark_noise_dominated(Context& cx, std::size_t k, std::size_t b, std::size_t r, double m, double margin) {
  const bool noisy = r < cx.data->conditions.size() && m < cx.motored_excess[r][b] * margin;
  cx.noise_dominated[k][b] = noisy;
  cx.tune_mask[k][b] = cx.base_mask[k][b] && !noisy;
}

// The masks of condition k, and its contribution to the band notes.
void mark_condition(Context& cx, std::size_t k, double margin) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t nb = data.band_count();
  const std::size_t r = nearest_ref(data, cx.refs, k);
  for (std::size_t b = 0; b < nb; ++b) {
    const double m = mean_meas(data, k, b);
    const bool ok = !data.bands[b].nyquist_cut && !data.band_line_free(k, b) && m > 0;
    // At a floor: the microphones within the margin of the background runs' level, or the pressure (so the
    // prediction) within the margin of the pressure chain's floor. Never fitted, never scored.
    const bool at_floor = (!cx.backgrounds.empty() && m < cx.background_ms[b] * margin) || cx.pfloor_band[k][b];
    cx.base_mask[k][b] = ok && !at_floor;
    cx.floor_limited[k][b] = ok && at_floor;
    mark_noise_dominated(cx, k, b, r, m, margin);
    if (data.band_line_free(k, b) && cx.band_notes[b].empty()) cx.band_notes[b] = "line_free";
  }
}

// Held-out conditions grouped by operating speed (leave-one-condition-out only): sorted by speed, a group holds the
// conditions within kGroupSpeedShare of its slowest. Empty when every group would be one condition (the group folds
// would be the condition folds) or when there is one group (nothing left to train on).
std::vector<std::vector<std::size_t>> speed_groups(const Context& cx) {
  constexpr double kGroupSpeedShare = 0.05;
  if (!cx.loo) return {};
  std::vector<std::size_t> by_speed(cx.heldout.size());
  std::iota(by_speed.begin(), by_speed.end(), 0);
  const auto speed = [&](std::size_t h) { return cx.data->conditions[cx.heldout[h]].mean_speed_rpm(); };
  std::stable_sort(by_speed.begin(), by_speed.end(), [&](std::size_t a, std::size_t b) { return speed(a) < speed(b); });
  std::vector<std::vector<std::size_t>> groups;
  for (std::size_t h : by_speed) {
    if (groups.empty() || speed(h) > (1.0 + kGroupSpeedShare) * speed(groups.back().front())) groups.emplace_back();
    groups.back().push_back(h);
  }
  const bool all_single = std::all_of(groups.begin(), groups.end(), [](const auto& g) { return g.size() == 1; });
  if (groups.size() < 2 || all_single) return {};
  for (auto& g : groups) std::sort(g.begin(), g.end());  // dataset order within a group
  return groups;
}

}  // namespace

void assign_roles(Context& cx) {
  const fit::BandDataset& data = *cx.data;
  const DiagnosisOptions& opt = *cx.opt;
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    const fit::ConditionInfo& i = data.conditions[k].info;
    if (i.background)
      cx.backgrounds.push_back(k);
    else if (i.motored)
      cx.refs.push_back(k);
    else
      cx.fired.push_back(k);
  }
  check_patterns_match(data, opt);
  cx.loo = opt.holdout.empty();
  for (std::size_t k : cx.fired) {
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
    throw std::invalid_argument(
        "diagnose: leave-one-condition-out needs at least two fired conditions (or give --holdout)");
  cx.groups = speed_groups(cx);
}

void mark_bands_and_floors(Context& cx, const BlockParams& start) {
  const fit::BandDataset& data = *cx.data;
  const std::size_t K = data.conditions.size(), nb = data.band_count();
  const double margin = std::pow(10.0, cx.opt->floor_margin_db / 10.0);
  cx.background_ms = background_levels(data, cx.backgrounds);
  cx.motored_excess = motored_excess(data, cx.refs, start);
  std::vector<std::size_t> scored = cx.train_fired;
  scored.insert(scored.end(), cx.heldout.begin(), cx.heldout.end());
  cx.fast = fit::window_capable_bands(data, scored);
  cx.pressure_floors.clear();
  for (std::size_t k = 0; k < K; ++k) cx.pressure_floors.push_back(fit::pressure_floor(data, k));
  cx.pfloor_band = fit::floor_limited_bands(data, &cx.pfloor_win);
  cx.base_mask.assign(K, std::vector<char>(nb, 0));
  cx.tune_mask.assign(K, std::vector<char>(nb, 0));
  cx.floor_limited.assign(K, std::vector<char>(nb, 0));
  cx.noise_dominated.assign(K, std::vector<char>(nb, 0));
  cx.band_notes.assign(nb, "");
  for (std::size_t b = 0; b < nb; ++b)
    if (data.bands[b].nyquist_cut) cx.band_notes[b] = "nyquist_cut";
  for (std::size_t k = 0; k < K; ++k) mark_condition(cx, k, margin);
}

bool remark_noise_dominated(Context& cx, const BlockParams& tuned) {
  const fit::BandDataset& data = *cx.data;
  const double margin = std::pow(10.0, cx.opt->floor_margin_db / 10.0);
  const std::vector<std::vector<char>> before = cx.tune_mask;
  cx.motored_excess = motored_excess(data, cx.refs, tuned);
  for (std::size_t k = 0; k < data.conditions.size(); ++k) {
    const std::size_t r = nearest_ref(data, cx.refs, k);
    for (std::size_t b = 0; b < data.band_count(); ++b)
      mark_noise_dominated(cx, k, b, r, mean_meas(data, k, b), margin);
  }
  return cx.tune_mask != before;
}

}  // namespace noisemon::model::diagnosis

namespace noisemon::model::diagnosis {

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

}  // namespace noisemon::model::diagnosis
