// Streaming simulation of the block model (eq. 4.13) on a sampled input.
//
// The input is treated as band-limited (not held, not linearly interpolated): it is interpolated onto an
// oversampled grid with a band-limited filter and integrated there with an L-stable implicit scheme that
// stays stable and accurate for any input amplitude (the cubic damper is stiff at high velocity). State is
// kept across calls, so a signal processed block by block gives the same output as in one piece.
#pragma once

#include <cstddef>
#include <memory>

#include "model/block_params.hpp"

namespace noisemon::model {

class BlockModel {
 public:
  // fs_hz: sample rate of input and output (the pipeline uses 40 kHz).
  BlockModel(const BlockParams& params, double fs_hz);
  ~BlockModel();
  BlockModel(BlockModel&&) noexcept;
  BlockModel& operator=(BlockModel&&) noexcept;

  // u: n input samples (Pa); y: n output samples (Pa); streaming, one output per input. The band-limited
  // interpolator needs a few future samples, so the output lags: counting samples from the last reset(),
  // output sample j is the model output at the instant of input sample j - latency_samples() (the first
  // latency_samples() outputs describe instants before the first input; they carry only the interpolator's
  // small pre-ringing of the first samples). In-place (u == y) is allowed.
  void process(const double* u, double* y, std::size_t n);
  std::size_t latency_samples() const;
  // Zero state (z = z' = 0, filters cleared).
  void reset();
  const BlockParams& params() const;
  double sample_rate_hz() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace noisemon::model
