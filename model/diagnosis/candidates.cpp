// The candidates: every effect of the list added to the baseline as a model extension, all parameters refitted
// on the training conditions, scored on the held-out ones and judged against the baseline by the bootstrap over
// cycles; ranked by the held-out gap, the simpler first when the better is not clearly better (by the bootstrap and by
// the information criterion, which counts every free level). Pairs: the best
// with every other one (one effect can hide another), and the close runner-up likewise.
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kCloseRunnerUp = 1.5;   // a runner-up within this factor of the best gap starts pairs too
constexpr double kThesisWorseDb = 0.05;  // a model this much worse on the thesis metric is never significant

// The pairs of `first` with every ranked candidate but itself and those in `skip`, appended to *combinations;
// best_pair follows the smallest gap.
void pairs_from(const Context& cx, const CandidateRound& round, std::size_t first, const std::vector<std::size_t>& skip,
                const std::vector<fit::BlockParam>& base_free, const ModelScore& baseline,
                std::vector<ModelScore>* combinations, std::optional<std::size_t>& best_pair, const StageLog& log) {
  for (std::size_t i : round.order) {
    if (i == first || std::find(skip.begin(), skip.end(), i) != skip.end()) continue;
    log.say("combination " + round.evals[first].score.name + " + " + round.evals[i].score.name);
    Evaluated e =
        evaluate(cx, combine(round.specs[first], round.specs[i]), round.evals[first].score.model, base_free, false);
    judge_pressure_law(cx, baseline, e.score);
    compare_with(e.score, baseline, cx.opt->min_improvement_db);
    combinations->push_back(e.score);
    if (!best_pair || e.score.heldout_gap_db < (*combinations)[*best_pair].heldout_gap_db)
      best_pair = combinations->size() - 1;
  }
}

}  // namespace

CandidateSpec spec_for(const std::string& name) {
  CandidateSpec s;
  s.name = name;
  s.effects = {name};
  if (name == "cubic_damping")
    s.extra_free = {fit::BlockParam::kB3};
  else if (name == "cubic_stiffness")
    s.extra_free = {fit::BlockParam::kK3};
  else if (name == "second_mode")
    s.ext.second_mode = true;
  else if (name == "mechanical_noise")
    s.ext.locked = true;
  else if (name == "background_noise")
    s.ext.stationary = true;
  else if (name == "transducer_noise")
    s.ext.transducer = true;
  else if (name == "mic_gain")
    s.ext.mic_gain = true;
  else if (name == "speed_dependence")
    s.ext.speed = true;
  else
    throw std::invalid_argument("unknown candidate effect '" + name + "'");
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
  for (fit::BlockParam p : b.extra_free)
    if (std::find(s.extra_free.begin(), s.extra_free.end(), p) == s.extra_free.end()) s.extra_free.push_back(p);
  return s;
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
  m.improvement_p05_db =
      d.empty() ? m.improvement_db : d[static_cast<std::size_t>(0.05 * static_cast<double>(d.size()))];
  m.win_fraction =
      d.empty() ? (m.improvement_db > 0 ? 1.0 : 0.0) : static_cast<double>(wins) / static_cast<double>(d.size());
  // No part of the composite gap may crown a model that makes the held-out thesis metric worse.
  m.thesis_worse = m.heldout_thesis_rms_db > ref.heldout_thesis_rms_db + kThesisWorseDb;
  m.pays_for_parameters = m.information_criterion < ref.information_criterion;
  m.group_worse = m.heldout_group_gap_db > ref.heldout_group_gap_db + kThesisWorseDb;
  m.significant = m.win_fraction >= 0.95 && m.improvement_db >= min_improvement && !m.thesis_worse && !m.refuted &&
                  m.pays_for_parameters;
  m.closes_band_db = std::sqrt(ref.part_band_ms) - std::sqrt(m.part_band_ms);
  m.closes_mic_db = std::sqrt(ref.part_mic) - std::sqrt(m.part_mic);
  m.closes_window_db = std::sqrt(ref.part_window_ms) - std::sqrt(m.part_window_ms);
}

double beats(const ModelScore& a, const ModelScore& b) {
  int w = 0;
  const std::size_t n = std::min(a.replicate_gaps.size(), b.replicate_gaps.size());
  for (std::size_t r = 0; r < n; ++r) w += a.replicate_gaps[r] < b.replicate_gaps[r] ? 1 : 0;
  return n > 0 ? static_cast<double>(w) / static_cast<double>(n) : (a.heldout_gap_db < b.heldout_gap_db ? 1.0 : 0.0);
}

CandidateRound evaluate_candidates(const Context& cx, const BlockParams& start, const Evaluated& base,
                                   const std::vector<fit::BlockParam>& base_free, StageLog& log) {
  const DiagnosisOptions& opt = *cx.opt;
  fit::ExtendedModel start_model;
  start_model.block = start;
  CandidateRound round;
  for (const std::string& n : opt.candidates.empty() ? candidate_effects() : opt.candidates) {
    log.say("candidate " + n);
    round.specs.push_back(spec_for(n));
    // Cubic coefficients change the waveform: their fit starts from the given model, not from a linear block
    // already bent to imitate them.
    const bool cubic = !round.specs.back().extra_free.empty();
    Evaluated e = evaluate(cx, round.specs.back(), cubic ? start_model : base.score.model, base_free, false);
    judge_pressure_law(cx, base.score, e.score);
    compare_with(e.score, base.score, opt.min_improvement_db);
    round.evals.push_back(std::move(e));
    log.stage("candidate " + n);
  }
  round.order = rank_candidates(round.evals, opt.min_improvement_db);
  return round;
}

std::vector<std::size_t> rank_candidates(const std::vector<Evaluated>& evals, double min_improvement_db) {
  std::vector<std::size_t> order(evals.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return evals[a].score.heldout_gap_db < evals[b].score.heldout_gap_db;
  });
  // The same bar a candidate must clear against the baseline.
  for (std::size_t pass = 0; pass < order.size(); ++pass)
    for (std::size_t i = 0; i + 1 < order.size(); ++i) {
      const ModelScore& a = evals[order[i]].score;
      const ModelScore& b = evals[order[i + 1]].score;
      const bool clearly_better = beats(a, b) >= 0.95 && b.heldout_gap_db - a.heldout_gap_db >= min_improvement_db &&
                                  a.information_criterion < b.information_criterion;
      if (b.parameters < a.parameters && b.significant && !clearly_better) std::swap(order[i], order[i + 1]);
    }
  return order;
}

std::optional<std::size_t> try_pairs(const Context& cx, const CandidateRound& round,
                                     const std::vector<std::size_t>& sig, const std::vector<fit::BlockParam>& base_free,
                                     const ModelScore& baseline, std::vector<ModelScore>* combinations,
                                     const StageLog& log) {
  std::optional<std::size_t> best_pair;
  pairs_from(cx, round, sig[0], {}, base_free, baseline, combinations, best_pair, log);
  const ModelScore& best = round.evals[sig[0]].score;
  if (sig.size() > 1 && best_pair && (*combinations)[*best_pair].heldout_gap_db > cx.opt->tolerance_db &&
      round.evals[sig[1]].score.heldout_gap_db <= kCloseRunnerUp * best.heldout_gap_db)
    pairs_from(cx, round, sig[1], {sig[0]}, base_free, baseline, combinations, best_pair, log);
  return best_pair;
}

}  // namespace noisemon::model::diagnosis

namespace noisemon::model::diagnosis {

const std::vector<std::string>& candidate_effects() {
  static const std::vector<std::string> names{"cubic_damping",    "cubic_stiffness",  "second_mode",
                                              "mechanical_noise", "background_noise", "transducer_noise",
                                              "mic_gain",         "speed_dependence"};
  return names;
}

}  // namespace noisemon::model::diagnosis
