#include "drivers/sim/sim_stopped.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "drivers/sim/sim_generators.hpp"

namespace noisemon::drivers::sim {

StoppedPressureGenerator::StoppedPressureGenerator(const SimConfig& config, double t_first_s)
    : chain_(config.pressure_chain, config.effects, config.seed),
      readout_(config.pressure_readout),
      static_pa_(1e5 * config.static_pressure_bar),
      next_(std::llround(t_first_s * kPipelineRateHz)),
      writer_(kPressureStreamChannels),
      batch_(SampleBlock::kMaxFrames) {}

void StoppedPressureGenerator::advance(double t_end_s, BlockRing& ring) {
  const auto end = static_cast<std::int64_t>(std::ceil(t_end_s * kPipelineRateHz));
  while (next_ < end) {
    const auto n = static_cast<std::size_t>(std::min<std::int64_t>(end - next_, SampleBlock::kMaxFrames));
    std::fill_n(batch_.begin(), n, static_pa_);
    chain_.measure(next_, batch_.data(), n);  // the noise counter-based on the frame, as on the edges when turning
    read_out_pressure(readout_, batch_.data(), n);
    for (std::size_t i = 0; i < n; ++i) {
      double* slot = writer_.frame(next_ + static_cast<std::int64_t>(i), ring);
      slot[kPressureChannel] = batch_[i];
      slot[kCrankChannel] = std::numeric_limits<double>::quiet_NaN();
    }
    next_ += static_cast<std::int64_t>(n);
  }
  writer_.flush(ring);
}

}  // namespace noisemon::drivers::sim
