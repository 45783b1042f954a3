#include "model/diagnosis/block_bootstrap.hpp"

#include <algorithm>
#include <random>
#include <utility>

namespace noisemon::model::diagnosis {

SignificanceTest block_bootstrap_test(const std::vector<std::vector<double>>& d, std::size_t block_samples,
                                      int resamples, std::uint64_t seed) {
  SignificanceTest t;
  std::size_t n = 0;
  double sum = 0.0;
  for (const auto& v : d)
    for (double x : v) {
      sum += x;
      ++n;
    }
  if (n == 0) return t;
  t.mean_reduction = sum / static_cast<double>(n);
  std::size_t len = block_samples;
  if (len == 0) {
    // Correlation length: first lag where the autocorrelation (pooled over segments) falls below 0.05.
    const std::size_t max_lag = std::max<std::size_t>(1, n / 20);
    double var = 0.0;
    for (const auto& v : d)
      for (double x : v) var += (x - t.mean_reduction) * (x - t.mean_reduction);
    std::size_t tau = max_lag;
    for (std::size_t lag = 1; lag < max_lag && var > 0; ++lag) {
      double c = 0.0;
      for (const auto& v : d)
        for (std::size_t i = lag; i < v.size(); ++i) c += (v[i] - t.mean_reduction) * (v[i - lag] - t.mean_reduction);
      if (c / var < 0.05) {
        tau = lag;
        break;
      }
    }
    len = std::clamp<std::size_t>(4 * tau, 16, std::max<std::size_t>(16, n / 20));
  }
  std::vector<std::pair<double, std::size_t>> blocks;
  for (const auto& v : d)
    for (std::size_t b = 0; b < v.size(); b += len) {
      const std::size_t e = std::min(v.size(), b + len);
      double s = 0.0;
      for (std::size_t i = b; i < e; ++i) s += v[i];
      blocks.emplace_back(s, e - b);
    }
  t.block_samples = len;
  t.blocks = blocks.size();
  std::mt19937_64 gen(seed);
  int exceed = 0;
  for (int r = 0; r < resamples; ++r) {
    double s = 0.0;
    std::size_t c = 0;
    for (std::size_t k = 0; k < blocks.size(); ++k) {
      const auto& b = blocks[gen() % blocks.size()];
      s += b.first;
      c += b.second;
    }
    // Under "no improvement" the bootstrap distribution is shifted to mean zero.
    if (s / static_cast<double>(c) - t.mean_reduction >= t.mean_reduction) ++exceed;
  }
  t.p_value = (1.0 + exceed) / (1.0 + resamples);
  return t;
}

}  // namespace noisemon::model::diagnosis
