// The law an additive candidate must obey (issue 22): a combustion-independent source is there in the motored runs
// too, at the level its own speed law gives, on top of what the motored pressure drives: the model with the source
// must not predict a motored run louder than its microphones measure (beyond the cycle-to-cycle error and a margin;
// where the bare model already overshoots, only what the source adds on top counts). A fit that does bent the
// source to sound only the fired runs hear, a pressure-driven effect, and is refuted. Bands where the motored
// pressure is at its floor (the prediction only an upper bound) tell nothing and are skipped.
// And the law a pressure-driven candidate must obey: what it changes, it changes in the motored runs too, which it is
// fitted on jointly with the fired ones; a fit that buys the fired runs' gap by predicting the motored runs worse than
// the baseline (their RMS error over the bands, beyond the cycle-to-cycle error and the same margin) is refuted.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kMarginDb = 1.0;        // beyond the cycle-to-cycle error: the model this much above the measurement
constexpr double kStandardErrors = 3.0;  // of the motored run's cycle-mean level in the band

// Cycle-mean band levels of a prediction, Pa^2.
std::vector<double> cycle_mean(const std::vector<double>& cycle_ms, std::size_t nb) {
  std::vector<double> m(nb, 0.0);
  const std::size_t nc = cycle_ms.size() / nb;
  for (std::size_t c = 0; c < nc; ++c)
    for (std::size_t b = 0; b < nb; ++b) m[b] += cycle_ms[c * nb + b] / static_cast<double>(nc);
  return m;
}

// A motored run's cycle-mean prediction per band by the model with its additive terms and without them; `upper`:
// the bare prediction is only an upper bound there (the pressure within its floor's margin).
struct MotoredPrediction {
  std::vector<double> full, bare;
  std::vector<char> upper;
};

MotoredPrediction predict_motored(const fit::BandDataset& data, std::size_t k, const fit::ExtendedModel& model) {
  const std::size_t nb = data.band_count();
  const fit::ConditionPrediction with = predict_condition(data, k, model, false);
  MotoredPrediction p{cycle_mean(with.cycle_ms, nb), {}, with.upper};
  p.bare = p.full;  // the additive sources add to the structure's prediction, which they do not change
  for (std::size_t b = 0; b < nb && b < with.additive_ms.size(); ++b) p.bare[b] -= with.additive_ms[b];
  p.upper.resize(nb, 0);
  return p;
}

// The measured cycle-mean level of band b and its standard error in dB (spread of the cycles' levels / sqrt(n)).
std::pair<double, double> measured_level(const fit::ConditionData& d, std::size_t b, const fit::ExtendedModel& model) {
  const std::size_t nc = d.cycle_count();
  double mean = 0.0, s = 0.0, s2 = 0.0;
  for (std::size_t c = 0; c < nc; ++c) {
    const double ms = fit::measured_ms(d, c, b, model);
    mean += ms / static_cast<double>(nc);
    const double l = db(std::max(ms, 1e-30));
    s += l;
    s2 += l * l;
  }
  const double n = static_cast<double>(nc);
  const double var = nc > 1 ? std::max(0.0, (s2 - s * s / n) / (n - 1.0)) : 0.0;
  return {mean, std::sqrt(var / std::max(1.0, n))};
}

std::vector<double> cycle_mean_prediction(const fit::BandDataset& data, std::size_t k, const fit::ExtendedModel& model,
                                          std::vector<char>& upper) {
  const fit::ConditionPrediction p = predict_condition(data, k, model, false);
  for (std::size_t b = 0; b < p.upper.size() && b < upper.size(); ++b) upper[b] = upper[b] || p.upper[b];
  return cycle_mean(p.cycle_ms, data.band_count());
}

// How much worse the candidate predicts motored run k than the baseline does, dB: the RMS over the judged bands of
// each model's error against the measurement (its own microphone gains applied), less the measurement's error.
// Judged: the bands the baseline is tuned on (`judged`: the structure's sound, not the combustion-independent noise
// that any added prediction would seem to explain), with the pressure above its floor. NaN when none.
double motored_worse_db(const fit::BandDataset& data, std::size_t k, const std::vector<char>& judged,
                        const fit::ExtendedModel& candidate, const fit::ExtendedModel& baseline) {
  const std::size_t nb = data.band_count();
  std::vector<char> upper(nb, 0);
  const std::vector<double> pc = cycle_mean_prediction(data, k, candidate, upper);
  const std::vector<double> pb = cycle_mean_prediction(data, k, baseline, upper);
  const fit::ConditionData& d = data.conditions[k];
  double ss_c = 0.0, ss_b = 0.0, ss_se = 0.0;
  std::size_t n = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    if (b >= judged.size() || !judged[b] || upper[b]) continue;
    const auto [meas_c, se_db] = measured_level(d, b, candidate);
    const double meas_b = measured_level(d, b, baseline).first;
    if (!(meas_c > 0) || !(meas_b > 0) || !(pc[b] > 0) || !(pb[b] > 0)) continue;
    ss_c += std::pow(db(pc[b] / meas_c), 2);
    ss_b += std::pow(db(pb[b] / meas_b), 2);
    ss_se += se_db * se_db;
    ++n;
  }
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  const double nn = static_cast<double>(n);
  return std::sqrt(ss_c / nn) - std::sqrt(ss_b / nn) - kStandardErrors * std::sqrt(ss_se / nn);
}

}  // namespace

void judge_pressure_law(const Context& cx, const ModelScore& baseline, ModelScore& m) {
  if (m.model.on.stationary || m.model.on.locked || cx.refs.empty()) return;
  m.pressure_law_checked = true;
  m.motored_worse_db = -std::numeric_limits<double>::infinity();
  for (std::size_t k : cx.refs) {
    const double worse = motored_worse_db(*cx.data, k, cx.tune_mask[k], m.model, baseline.model);
    if (worse > m.motored_worse_db) {
      m.motored_worse_db = worse;
      m.motored_worse_where = cx.data->conditions[k].info.name;
    }
  }
  if (m.motored_worse_db > kMarginDb) m.refuted = true;
}

void judge_motored_law(const Context& cx, ModelScore& m) {
  if (!(m.model.on.stationary || m.model.on.locked) || cx.refs.empty()) return;
  const fit::BandDataset& data = *cx.data;
  m.motored_law_checked = true;
  m.motored_overshoot_db = -std::numeric_limits<double>::infinity();
  for (std::size_t k : cx.refs) {
    const fit::ConditionData& d = data.conditions[k];
    const MotoredPrediction p = predict_motored(data, k, m.model);
    for (std::size_t b = 0; b < data.band_count(); ++b) {
      if (data.bands[b].nyquist_cut || data.band_line_free(k, b) || p.upper[b]) continue;
      const double add = p.full[b] - p.bare[b];
      const auto [meas, se_db] = measured_level(d, b, m.model);
      if (!(meas > 0) || !(add > 0) || !(p.bare[b] > 0)) continue;
      // What the source adds to the model's motored prediction beyond what the motored run measures (the bare
      // model's own overshoot, if any, is not the source's), less the measurement's error.
      const double beyond = db(p.full[b] / meas) - std::max(0.0, db(p.bare[b] / meas)) - kStandardErrors * se_db;
      if (beyond > m.motored_overshoot_db) {
        m.motored_overshoot_db = beyond;
        m.motored_overshoot_where =
            d.info.name + " " + std::to_string(static_cast<int>(data.bands[b].nominal_hz)) + " Hz";
      }
    }
  }
  m.refuted = m.motored_overshoot_db > kMarginDb;
}

}  // namespace noisemon::model::diagnosis
