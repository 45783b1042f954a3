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

// How the input is taken between its samples. The pipeline's pressure is band-limited (the default); a
// DAC-driven test rig may hold its output between updates (zero-order hold) or ramp (first-order hold).
enum class InputInterpolation { band_limited, zero_order_hold, piecewise_linear };

// Options for uses other than the 40 kHz pipeline (waveform fitting at any sample rate). The defaults are
// the pipeline's behaviour.
struct BlockModelOptions {
  InputInterpolation input = InputInterpolation::band_limited;
  // Longest integration step (s); each sample interval is split into equal steps no longer than this.
  double max_step_s = 25e-6;
  // Halve steps where the error estimate asks for it. Fitting by finite differences turns it off: the
  // refinement decisions jump with the parameters, which would corrupt the difference quotients.
  bool refine = true;
};

class BlockModel {
 public:
  // fs_hz: sample rate of input and output (the pipeline uses 40 kHz).
  BlockModel(const BlockParams& params, double fs_hz);
  BlockModel(const BlockParams& params, double fs_hz, const BlockModelOptions& options);
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
  // Position z and velocity z' at the instant of the last output (the input history is kept): sets the
  // initial condition of a simulation started after priming the interpolator with the first inputs.
  void set_state(double z, double v);
  double position() const;
  double velocity() const;
  const BlockModelOptions& options() const;
  const BlockParams& params() const;
  double sample_rate_hz() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace noisemon::model
