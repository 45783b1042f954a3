// Whether a candidate's improvement on held-out data is more than chance: a one-sided block bootstrap of the mean of
// the per-sample reductions e_before^2 - e_after^2, whose blocks keep neighbouring (correlated) samples together.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace noisemon::model::diagnosis {

struct SignificanceTest {
  double mean_reduction = 0.0;  // mean over held-out samples of e_before^2 - e_after^2
  double p_value = 1.0;
  std::size_t block_samples = 0;
  std::size_t blocks = 0;
};

// One-sided block-bootstrap test that the mean of d (pooled over segments) is positive. Blocks of
// `block_samples` neighbouring values never cross a segment; 0 chooses the length from d's correlation.
SignificanceTest block_bootstrap_test(const std::vector<std::vector<double>>& d, std::size_t block_samples,
                                      int resamples, std::uint64_t seed);

}  // namespace noisemon::model::diagnosis
