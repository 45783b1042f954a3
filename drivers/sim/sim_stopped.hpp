// The virtual engine at rest ([sim] stopped = true): no encoder edges clock the pressure, so the card samples it on
// its timer instead, at the pipeline's 40 kHz, with the crank angle unknown (NaN). The cylinder holds a static
// pressure (ambient, or what a dead-weight tester applies), measured through the configured pressure chain (its
// floor, flicker, ADC, zero and gain error) and the card's conversion: what `noisemon calibrate --pressure` and
// `noisemon check` look at.
#pragma once

#include <cstdint>
#include <vector>

#include "drivers/block_writer.hpp"
#include "drivers/sim/sim_source.hpp"
#include "model/engine/pressure_chain.hpp"

namespace noisemon::drivers::sim {

class StoppedPressureGenerator {
 public:
  StoppedPressureGenerator(const SimConfig& config, double t_first_s);
  void advance(double t_end_s, BlockRing& ring);  // every 40 kHz frame before t_end_s
  std::uint64_t blocks_written() const { return writer_.blocks_written(); }
  std::uint64_t clipped_samples() const { return chain_.clipped_samples(); }

 private:
  model::engine::PressureChain chain_;
  SimConfig::PressureReadout readout_;
  double static_pa_;
  std::int64_t next_;  // the next frame on the 40 kHz grid
  BlockWriter writer_;
  std::vector<double> batch_;
};

}  // namespace noisemon::drivers::sim
