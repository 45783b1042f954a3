// The waveform model's fixed-step simulation as the waveform fit uses it (waveform_fit.hpp declares the public
// simulation: simulate_waveform, free_run_errors, ...): runs over sample ranges from an estimated initial state,
// the states' scale, the step chosen for a model, and the output gains by linear least squares on the states.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "model/fit/waveform_fit.hpp"

namespace noisemon::model::fit::detail {

using State = std::array<double, 4>;  // z, z', and the second mode's w, w'

// Throws std::invalid_argument unless range r lies in n samples and holds more than `settle` of them.
void check_range(SampleRange r, std::size_t n, std::size_t settle);

// The model's output over range r at `steps` integration steps per sample, from the initial state that best
// explains the first settle_samples of y.
std::vector<double> simulate_with_steps(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                                        std::span<const double> u, std::span<const double> y, SampleRange r);

// The rms of each state and the peak displacement over the ranges (after settling), from the held-first-input
// equilibrium: the scales of the fit's coordinates.
struct StateRms {
  std::array<double, 4> rms{};
  double z_peak = 0.0;
};
StateRms state_rms(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                   std::span<const double> u, std::span<const SampleRange> ranges);

// The fixed step of a simulation: given, or chosen from the model and (for a cubic spring) the peak
// displacement it reaches on the ranges.
int steps_for(const WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, std::span<const double> u,
              std::span<const SampleRange> ranges);

// The rms of x over the ranges.
double signal_rms(std::span<const double> x, std::span<const SampleRange> ranges);

// Free output gains (c0, c1, c0_2, c1_2, y_offset among `free`) by linear least squares on the recorded states.
void least_squares_gains(WaveformModel& m, double fs_hz, const WaveformSimOptions& sim, int steps,
                         std::span<const double> u, std::span<const double> y, std::span<const SampleRange> ranges,
                         const std::vector<std::string>& free);

}  // namespace noisemon::model::fit::detail
