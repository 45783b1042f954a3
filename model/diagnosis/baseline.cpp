// The baseline: the start model (default free k1, b1, c0, c1) tuned on the training conditions, on the bands
// where combustion noise dominates, and scored on the held-out ones: the gap every candidate is measured against,
// and that gap's bootstrap noise, below which the verdict is `none`.
#include <algorithm>
#include <cmath>

#include "model/diagnosis/stages.hpp"

namespace noisemon::model::diagnosis {

Evaluated tune_baseline(const Context& cx, const BlockParams& start, const std::vector<fit::BlockParam>& base_free) {
  fit::ExtendedModel start_model;
  start_model.block = start;
  return evaluate(cx, CandidateSpec{}, start_model, base_free, true);
}

double bootstrap_noise_db(const ModelScore& m) {
  double mean = 0.0, s = 0.0;
  const auto& r = m.replicate_gaps;
  for (double x : r) mean += x;
  mean /= std::max<std::size_t>(1, r.size());
  for (double x : r) s += (x - mean) * (x - mean);
  return r.size() > 1 ? std::sqrt(s / static_cast<double>(r.size() - 1)) : 0.0;
}

}  // namespace noisemon::model::diagnosis
