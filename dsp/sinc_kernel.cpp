#include "dsp/sinc_kernel.hpp"

#include <numeric>

#include "dsp/fir_design.hpp"

namespace noisemon::dsp::sinc_kernel {
namespace {

// The kernel table: row r, tap k is the windowed sinc at offset r / R + W - 1 - k (tap k is sample
// cursor - W + 1 + k).
std::vector<double> interpolation_table() {
  std::vector<double> table((kKernelPhases + 1) * kKernelTaps);
  const double beta = fir::kaiser_beta(kKernelAttenuationDb);
  const auto w = static_cast<double>(kKernelHalfWidth);
  for (std::size_t r = 0; r <= kKernelPhases; ++r) {
    double* row = &table[r * kKernelTaps];
    for (std::size_t k = 0; k < kKernelTaps; ++k) {
      const double d = static_cast<double>(r) / kKernelPhases + w - 1.0 - static_cast<double>(k);
      row[k] = fir::sinc(d) * fir::kaiser_window(d / w, beta);
    }
    // Rows sum to 1, so do blends of neighbouring rows: DC passes exactly (pressure rides on a large mean).
    const double sum = std::accumulate(row, row + kKernelTaps, 0.0);
    for (std::size_t k = 0; k < kKernelTaps; ++k) row[k] /= sum;
  }
  return table;
}

}  // namespace

// Built once per process (a restarted stream reuses it).
const std::vector<double>& shared_interpolation_table() {
  static const std::vector<double> table = interpolation_table();
  return table;
}

}  // namespace noisemon::dsp::sinc_kernel
