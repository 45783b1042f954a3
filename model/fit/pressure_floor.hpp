// The floors of the measurement chains (docs/sources-and-formats.md, "The simulated engine"), for the fit and the
// diagnosis.
//
// Pressure chain. Every real pressure chain (transducer, charge amplifier, ADC) adds a broadband floor to the
// MEASURED pressure that the engine never hears: a model driven by the measured pressure predicts sound there
// that no microphone hears. Every prediction therefore subtracts what the judged floor drives (model/fit/band_fit), and
// the cells where the pressure is within kFloorMarginDb of the floor are floor-limited (model/diagnosis).
//  - Stated: the run's commissioned floor (run.json "pressure.noise_floor_bar", rms per encoder sample) is taken as
//    white over the encoder's bandwidth: one-sided density 2 sigma^2 / f_encoder up to min(f_encoder / 2, 20 kHz).
//  - Estimated: always, from the data itself, per band: the crank window with the least pressure (the quiet
//    gas-exchange strokes, where the true pressure is smooth and carries almost nothing but the floor in the fast
//    bands), cycle-averaged, over the band's noise bandwidth. No shape is assumed (real chains are not white: the
//    real Yanmar record's floor rises with frequency). Bands too slow for a crank window (below about 1 kHz) take
//    the density of the lowest band estimated. It is an upper bound of the floor: real content in the quiet
//    windows can only raise it.
// A stated floor is the one the cells are judged by (the transducer_noise candidate then looks for more floor than
// stated); without one the estimate is.
//
// Microphones. Their floor (self-noise, the test cell's background) is measured by background runs (engine off)
// when given; otherwise the quiet windows' microphone level is reported as its estimate (it cannot be told from
// stationary background noise, a candidate effect, so it is not used to exclude cells).
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include "model/fit/band_dataset.hpp"

namespace noisemon::model::fit {

// The margin above a floor below which a cell is floor-limited (ISO 3744's 6 dB for background noise): the floor
// then makes more than a quarter of the measured (or of the predicted) power.
inline constexpr double kFloorMarginDb = 6.0;

struct PressureFloor {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> density;    // per band: the floor the cells are judged by, one-sided Pa^2/Hz (empty: none)
  bool stated = false;            // density comes from the run's commissioned floor
  std::vector<double> estimated;  // per band: the estimate from the quiet crank windows (empty: none possible)
  double estimated_white = kNaN;  // the estimate's median density over the bands it was made in, Pa^2/Hz
  std::vector<double> band_ms;    // per band: the judged floor's mean square through the band's filter, Pa^2
  // The estimate as rms per encoder sample of a white floor of density estimated_white (NaN without the encoder
  // rate), and as the rms of the estimated floor over the 40 kHz grid.
  double estimated_rms_per_sample_pa(double encoder_rate_hz) const;
  double estimated_rms_on_grid_pa(const BandDataset& data) const;
};

// The pressure floor of one condition (see the top of the file).
PressureFloor pressure_floor(const BandDataset& data, std::size_t condition);

// Sets every condition's ConditionInfo::floor_density to its judged floor: what every prediction allows for.
// Background runs (engine off) get none. make_dataset calls it; call it again after changing a condition's
// pressure_floor_pa.
void judge_pressure_floors(BandDataset& data);

// Per condition, per band: the cycle-mean pressure is within kFloorMarginDb of the judged floor (ConditionInfo::
// floor_density): the band's prediction is floor-limited, never to be fitted or scored. Per band and crank window
// [b * W + w] in *windows when given.
// (What judge_pressure_floors stored in each ConditionInfo, all false where no floor was judged.)
std::vector<std::vector<char>> floor_limited_bands(const BandDataset& data,
                                                   std::vector<std::vector<char>>* windows = nullptr);
// The same for one condition, computed from its floor_density (judge_pressure_floors stores it).
std::vector<char> floor_limited_cells(const BandDataset& data, std::size_t condition,
                                      std::vector<char>* windows = nullptr);

// Noise bandwidth of a band's filter (the integral of its power response) from 0 to f_max, Hz.
double band_noise_bandwidth(const dsp::ThirdOctaveBand& band, double f_max_hz);

// Per band and crank window: the condition's cycle-mean pressure mean square (Pa^2) [b * W + w]; per band [b].
std::vector<double> mean_window_cpl(const ConditionData& d);
std::vector<double> mean_band_cpl(const ConditionData& d);

// Per band: the microphones' quiet-window level (mean square, Pa^2): the lowest cycle-mean window level of the
// microphone average, in the bands fast enough for a crank window (NaN elsewhere).
std::vector<double> quiet_window_mic_ms(const BandDataset& data, std::size_t condition);

// Bands whose filter settles within the shortest crank window of the conditions (window levels mean something).
std::vector<char> window_capable_bands(const BandDataset& data, const std::vector<std::size_t>& conditions);

}  // namespace noisemon::model::fit
