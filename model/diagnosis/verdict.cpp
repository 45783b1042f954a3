// The verdict: `none` when the baseline's held-out gap is within the tolerance or its bootstrap noise; else the
// best significant candidate (with a partner when a pair is clearly better) when it closes at least
// min_closed_fraction of the gap or leaves no more than the tolerance; otherwise `unexplained`, never a forced name.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {
namespace {

constexpr double kPairShare = 0.2;  // a second effect must close this share of the best one's remaining gap

std::string percent(double fraction) { return std::to_string(static_cast<int>(std::lround(100 * fraction))); }

// Per band: RMS of a model's gap over the held-out conditions (NaN where none is scored).
std::vector<double> per_band_rms(const ModelScore& m, std::size_t nb) {
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
}

// The held-out gap of a single candidate by name (infinite when it was not tried alone).
double gap_alone(const CandidateRound& round, const std::string& name) {
  for (const Evaluated& e : round.evals)
    if (e.score.name == name) return e.score.heldout_gap_db;
  return std::numeric_limits<double>::infinity();
}

// The best significant candidate, or the best pair with it when that is clearly better: v.effect (and v.also,
// *partner) name it; returns the selected model.
const ModelScore* select_model(const Context& cx, const CandidateRound& round, const std::vector<std::size_t>& sig,
                               const std::vector<fit::BlockParam>& base_free, DiagnosisResult& res, StageLog& log,
                               std::string* partner) {
  const DiagnosisOptions& opt = *cx.opt;
  Verdict& v = res.verdict;
  const ModelScore& best = round.evals[sig[0]].score;
  v.effect = best.name;
  if (!(round.order.size() > 1 && best.heldout_gap_db > opt.tolerance_db)) return &best;
  // A second effect on top of the best: tried with every other candidate, significant alone or not (one effect can
  // hide another: a cubic spring's detuning under a cubic damper's flattening), and from the close runner-up too
  // (try_pairs). The best pair is kept when it beats the best single in 95 % of the replicates by at least
  // kPairShare of its gap (and min_improvement_db), so that a free term riding along for a few hundredths of a dB
  // is not named; of its two effects the one better alone is the verdict, the other its partner.
  const std::optional<std::size_t> best_pair =
      try_pairs(cx, round, sig, base_free, res.baseline, &res.combinations, log);
  log.stage("combinations");
  bool keep = false;
  if (best_pair) {
    const ModelScore& pair = res.combinations[*best_pair];
    const double gain = best.heldout_gap_db - pair.heldout_gap_db;
    keep = !pair.thesis_worse && beats(pair, best) >= 0.95 &&
           gain >= std::max(opt.min_improvement_db, kPairShare * best.heldout_gap_db);
  }
  // Best first, for the report: the pair with the smallest gap (best_pair) comes to the front.
  std::stable_sort(res.combinations.begin(), res.combinations.end(),
                   [](const ModelScore& a, const ModelScore& b) { return a.heldout_gap_db < b.heldout_gap_db; });
  if (!keep) return &best;
  const ModelScore* selected = &res.combinations.front();
  std::string first = selected->effects.front(), second = selected->effects.back();
  if (gap_alone(round, second) < gap_alone(round, first)) std::swap(first, second);
  v.effect = first;
  v.also.push_back(second);
  *partner = second;
  return selected;
}

// Unexplained when a significant gap remains: what the selected model leaves within the tolerance is no such gap,
// however small a share of a gap barely above the tolerance it closed.
void conclude(Verdict& v, const ModelScore& selected, const DiagnosisOptions& opt) {
  const double closed = 1.0 - selected.heldout_gap_db / v.heldout_rms_before_db;
  if (closed < opt.min_closed_fraction && selected.heldout_gap_db > opt.tolerance_db) {
    const std::string best_name = v.effect;
    v.effect = "unexplained";
    v.also.clear();
    v.explanation =
        "a significant gap remains: the best candidate (" + best_name + ") closes only " + percent(closed) + " % of it";
  } else {
    v.explanation = v.effect + " closes " + percent(closed) + " % of the held-out gap";
    if (!v.also.empty()) v.explanation += " together with " + v.also.front();
  }
}

// A gap within the tolerance that a candidate still closes significantly: named beside `none`, not as the verdict
// (the tolerance is the user's line between agreement and a gap worth a cause).
void note_below_tolerance(const ModelScore& best, Verdict& v) {
  v.below_tolerance = best.name;
  v.below_tolerance_after_db = best.heldout_gap_db;
  char text[160];
  std::snprintf(text, sizeof text, "; below it, %s closes the gap significantly (%.2f -> %.2f dB)", best.name.c_str(),
                v.heldout_rms_before_db, best.heldout_gap_db);
  v.explanation += text;
}

}  // namespace

void judge(const Context& cx, const CandidateRound& round, const std::vector<fit::BlockParam>& base_free,
           DiagnosisResult& res, StageLog& log) {
  const DiagnosisOptions& opt = *cx.opt;
  Verdict& v = res.verdict;
  v.heldout_rms_before_db = res.baseline.heldout_gap_db;
  v.heldout_thesis_before_db = res.baseline.heldout_thesis_rms_db;
  v.noise_db = bootstrap_noise_db(res.baseline);
  std::vector<std::size_t> sig;
  for (std::size_t i : round.order)
    if (round.evals[i].score.significant) sig.push_back(i);
  const ModelScore* selected = nullptr;
  std::string partner;  // the second effect kept with the verdict's
  if (v.heldout_rms_before_db <= opt.tolerance_db || v.heldout_rms_before_db <= 2.0 * v.noise_db) {
    v.effect = "none";
    v.explanation = "the tuned baseline already agrees with the held-out conditions within the tolerance (" +
                    std::to_string(opt.tolerance_db).substr(0, 4) + " dB) and the cycle-to-cycle noise";
    if (!sig.empty() && v.heldout_rms_before_db > 2.0 * v.noise_db) note_below_tolerance(round.evals[sig[0]].score, v);
  } else if (sig.empty()) {
    v.effect = "unexplained";
    v.explanation = "a significant gap remains and no candidate effect reduces it significantly";
  } else {
    selected = select_model(cx, round, sig, base_free, res, log, &partner);
    conclude(v, *selected, opt);
  }
  for (ModelScore& c : res.candidates)
    if (!partner.empty() && !v.also.empty() && c.name == partner) c.significant_on_top = true;
  const ModelScore& after = (selected && v.effect != "unexplained" && v.effect != "none") ? *selected : res.baseline;
  v.heldout_rms_after_db = after.heldout_gap_db;
  v.heldout_thesis_after_db = after.heldout_thesis_rms_db;
  v.gap_closed_fraction = v.heldout_rms_before_db > 0 ? 1.0 - v.heldout_rms_after_db / v.heldout_rms_before_db : 0.0;
  const std::size_t nb = cx.data->band_count();
  v.band_before_db = per_band_rms(res.baseline, nb);
  v.band_after_db = per_band_rms(after, nb);
  v.remaining = describe_remaining(cx, after, v.band_after_db);
}

}  // namespace noisemon::model::diagnosis
