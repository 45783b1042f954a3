// Waveform-mode tuning: fit the block model (eq. 4.13, optionally with a second mode and offsets) to an
// input/output time series at any sample rate by free-run simulation error, with Ceres.
//
// Free run: each segment is simulated from the input alone; only its first `settle_samples` outputs are
// used, to estimate the initial state (least squares over the state, as the nonlinear-benchmark protocol
// "use the first 50 samples to settle" allows), and they are not scored. The error is the simulated minus
// the measured output over the rest of the segment.
//
// Parametrisation (what Ceres moves; all O(1) at the start):
//   k1, b1, k1_2, b1_2   log(p / p_start): positive, scale-free; bounds: a factor 1e3 either way.
//   k3                   k3 = theta * k1 / z_rms^2: theta is the cubic spring force relative to the linear
//                        one at the start model's rms displacement. Linear in theta, so the fit can start
//                        at k3 = 0 (a log scale cannot) and stop there; bounds [0, 1e3] (a hardening spring:
//                        a softening one loses its stability at large amplitude).
//   b3                   b3 = theta * b1 / v_rms^2, the same for the damper; bounds [0, 1e3].
//   c0, c1, c0_2, c1_2   signed, theta * (typical size) (an output gain may be 0 or negative).
//   u_offset, y_offset   signed, theta * rms of the input / output.
// The start is the given model, or the nearest (lowest training error) of the Table 4.1 presets whose
// resonance lies below the Nyquist frequency and a linear second-order estimate from the data (an ARX
// model converted to continuous time); free output gains and offsets of the start are set by linear least
// squares. The fixed integration step is chosen from the model (see choose_steps_per_sample) and the fit is
// repeated once if the fitted model needs finer steps.
//
// Uncertainty: cov = s^2 (J^T J)^-1 at the optimum, J the Jacobian of the free-run output with respect to
// the parameters (central differences), s^2 = SSE / (N - p). It assumes white residuals; a long waveform
// with a coloured model error makes it optimistic, which sigma_blocks (the same with the residual's
// correlation over blocks, a sandwich estimate) shows.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "model/block_model.hpp"
#include "model/block_params.hpp"
#include "model/second_mode_model.hpp"

namespace noisemon::model::fit {

// Half-open sample-index range [begin, end).
struct SampleRange {
  std::size_t begin = 0;
  std::size_t end = 0;
  std::size_t size() const { return end > begin ? end - begin : 0; }
};

// Everything waveform mode can fit.
struct WaveformModel {
  BlockParams block;
  bool has_second_mode = false;
  SecondModeParams second;
  double u_offset = 0.0;  // subtracted from the input (a bias of the input channel)
  double y_offset = 0.0;  // added to the model output (a bias of the output channel)
};

// Names of the parameters that can be freed: k1 b1 k3 b3 c0 c1 k1_2 b1_2 c0_2 c1_2 u_offset y_offset.
const std::vector<std::string>& waveform_parameter_names();
// Throw std::invalid_argument naming the parameter when it is unknown.
double get_parameter(const WaveformModel& m, std::string_view name);
void set_parameter(WaveformModel& m, std::string_view name, double value);

struct WaveformSimOptions {
  InputInterpolation input = InputInterpolation::band_limited;
  int steps_per_sample = 0;         // fixed integration steps per sample; 0: choose_steps_per_sample
  std::size_t settle_samples = 50;  // per segment: initial-state estimation only, not scored
};

// Steps per sample so that h * omega <= 0.3 (Radau IIA then errs by ~1e-5 relative), omega the highest
// natural frequency of the model, the cubic spring's stiffening at displacement z_peak included.
int choose_steps_per_sample(const WaveformModel& m, double fs_hz, double z_peak = 0.0);

// Free-run output over range r (every sample of it, the settle samples included). u and y are the whole
// record; y is read only on the settle samples. Throws std::invalid_argument when r does not fit.
std::vector<double> simulate_waveform(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim,
                                      std::span<const double> u, std::span<const double> y, SampleRange r);

// The same with the primary mode's position z and velocity z' at every sample (for diagnosis features).
struct WaveformTrace {
  std::vector<double> y, z, v;
};
WaveformTrace simulate_waveform_trace(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim,
                                      std::span<const double> u, std::span<const double> y, SampleRange r);

struct SegmentError {
  double sse = 0.0;       // sum of squared errors over the scored samples
  std::size_t count = 0;  // scored samples
  double rms() const;
};
// Scored error of each range, and pooled.
std::vector<SegmentError> free_run_errors(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim,
                                          std::span<const double> u, std::span<const double> y,
                                          std::span<const SampleRange> ranges);
SegmentError pooled(std::span<const SegmentError> errors);

// Linear second-order estimate from the data (ARX(2,3) by least squares, poles mapped to continuous time,
// output gains by least squares on the free-run states); nullopt when the data show no stable second-order
// dynamics.
std::optional<WaveformModel> linear_estimate_from_data(std::span<const double> u, std::span<const double> y,
                                                       double fs_hz, std::span<const SampleRange> train,
                                                       const WaveformSimOptions& sim);

struct WaveformFitProgress {
  int iteration = 0;
  double train_rms = 0.0;  // data units
  bool step_accepted = false;
  double seconds = 0.0;
  WaveformModel model;  // current parameters
};

struct WaveformFitOptions {
  double fs_hz = 0.0;
  std::vector<SampleRange> train;
  std::vector<SampleRange> heldout;  // scored only
  std::vector<std::string> free_params = {"k1", "b1", "c0", "c1"};
  std::optional<WaveformModel> start;  // nullopt: nearest preset or the data's linear estimate
  std::string start_name;              // how the given start is called in reports ("given" when empty)
  WaveformSimOptions sim;
  int max_iterations = 60;
  double function_tolerance = 1e-9;  // relative decrease of the cost that ends the fit
  bool refine_start_gains = true;    // free c0, c1 (c0_2, c1_2, y_offset) of the start by least squares
  std::function<void(const WaveformFitProgress&)> progress;  // each iteration (nothing printed otherwise)
};

struct WaveformFitResult {
  WaveformModel model;
  WaveformModel start;
  std::string start_name;
  std::vector<std::string> free_params;
  std::vector<double> sigma;         // 1-sigma per free parameter, s^2 (J^T J)^-1
  std::vector<double> sigma_blocks;  // the same allowing for residual correlation (block sandwich)
  std::vector<bool> at_bound;        // the parameter ended on a bound
  double start_train_rms = 0.0;
  double train_rms = 0.0;
  std::size_t train_samples = 0;
  double heldout_rms = 0.0;  // pooled over the held-out ranges (NaN without any)
  std::vector<double> heldout_segment_rms;
  std::size_t heldout_samples = 0;
  double residual_sigma = 0.0;  // s
  int iterations = 0;
  bool converged = false;
  std::string solver_message;
  int steps_per_sample = 0;
  double seconds = 0.0;
};

// Throws std::invalid_argument for unusable options (naming the option) and std::runtime_error when the
// model cannot be simulated on the data.
WaveformFitResult fit_waveform(std::span<const double> u, std::span<const double> y, const WaveformFitOptions& opt);

}  // namespace noisemon::model::fit
