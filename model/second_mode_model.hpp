// The block model with a second structural mode: a further linear mass-spring-damper (m = 1 kg) driven by
// the same input, whose output adds to the block model's (the effect `second_mode`):
//   z'' = u - k1 z - k3 z^3 - b1 z' - b3 z'^3,   w'' = u - k1_2 w - b1_2 w',
//   y = C0 z + C1 z' + C0_2 w + C1_2 w'.
// Two BlockModels side by side, so eq. 4.13's integrator and its band-limited input are reused unchanged.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "model/block_model.hpp"
#include "model/block_params.hpp"

namespace noisemon::model {

struct SecondModeParams {
  double k1 = 0.0;  // N/m   (mode frequency sqrt(k1_2 / 1 kg))
  double b1 = 0.0;  // N s/m
  double c0 = 0.0;  // output gain on displacement
  double c1 = 0.0;  // output gain on velocity
};

class SecondModeModel {
 public:
  SecondModeModel(const BlockParams& primary, const SecondModeParams& second, double fs_hz,
                  const BlockModelOptions& options = {});

  // Same streaming contract and latency as BlockModel::process. In-place is allowed.
  void process(const double* u, double* y, std::size_t n);
  std::size_t latency_samples() const { return primary_.latency_samples(); }
  void reset();
  // Positions and velocities of both modes at the instant of the last output (see BlockModel::set_state).
  void set_state(double z, double v, double w, double w_dot);
  const BlockModel& primary() const { return primary_; }
  const BlockModel& second() const { return second_; }

 private:
  BlockModel primary_;
  BlockModel second_;
  static constexpr std::size_t kChunk = 256;
  std::array<double, kChunk> in_{}, out_{};  // scratch: no allocation per call
};

}  // namespace noisemon::model
