// The band dataset the fit and the diagnosis work on: per condition (operating point) and per engine cycle,
// the 1/3-octave band mean squares of the cylinder pressure (CPL) and of every microphone, per crank-angle
// window of the microphone average, and the pressure itself for re-simulating the block model.
//
// The numbers come from the live pipeline's bank (dsp::ThirdOctaveBank at 40 kHz, the same IEC 61260-1
// filters), cycles cut where the crank angle wraps from +360 to -360 deg, microphone frame n + d paired with
// pressure frame n (d = acoustic delay in frames), exactly as daemon/cycle_processor does. Levels and the
// A-weighting are applied by the callers (the A-weighting cancels in the gap: both curves of eq. 2.1 carry it).
//
// Settling: the recording's first complete cycle is repeated `preroll_cycles` times in front of it (a periodic
// extension: the engine was running before the recording started) so that the bank's slow low bands are not
// measuring a start-up transient; every channel, measured or re-simulated, sees the same pre-roll. Constant
// offsets (mean pressure, the model's static deflection) are removed before the bank for the same reason.
//
// Bands that carry no information are flagged, not hidden: the band cut by the Nyquist frequency, and low
// bands holding no harmonic of the cycle frequency (their level is filter leakage from the neighbouring
// harmonics, which the tiniest phase difference changes).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "dsp/third_octave_bank.hpp"

namespace noisemon::model::fit {

inline constexpr double kDatasetRateHz = 40000.0;
inline constexpr std::size_t kCrankWindows = 8;   // 90-degree crank-angle windows per 720-degree cycle
inline constexpr std::size_t kW = kCrankWindows;  // its short name in the fits' arithmetic

// What a condition is (from run.json / the operating point).
struct ConditionInfo {
  std::string name;
  double speed_rpm = 0.0;
  double load_nm = 0.0;
  double soi_deg_btdc = 0.0;
  bool motored = false;
  bool background = false;  // engine off: a background-noise measurement (the irreducible floor)
  // The pressure chain: its commissioned floor, Pa rms per encoder sample (NaN: unknown, estimated from the data),
  // and the encoder's mean sample rate in Hz (NaN: unknown, e.g. a log already on the 40 kHz grid).
  double pressure_floor_pa = std::numeric_limits<double>::quiet_NaN();
  double encoder_rate_hz = std::numeric_limits<double>::quiet_NaN();
  // The floor the predictions allow for (model/fit/pressure_floor: judge_pressure_floors): per band, the one-sided
  // density of the pressure chain's noise in the measured pressure, Pa^2/Hz; empty: none.
  std::vector<double> floor_density;
  // Set with floor_density: per band, and per band * W ([b * W + w]), the pressure within kFloorMarginDb of that
  // floor (model/fit/pressure_floor.hpp); empty without a floor.
  std::vector<char> floor_limited_band, floor_limited_window;
};

// One contiguous recording of a condition on the 40 kHz grid, as the loader hands it over.
struct ConditionRecording {
  std::vector<double> pressure_pa;  // one per frame
  std::vector<double> crank_deg;    // one per frame, wrapped to [-360, 360)
  std::vector<double> mics_pa;      // frames * mic_count, frame-major
  std::size_t mic_count = 0;
  std::int64_t delay_frames = 0;  // acoustic delay: microphone frame n + d belongs to pressure frame n
};

// A recording prepared for the bank: the pre-roll plus the complete cycles, and where they are.
struct PreparedSegment {
  std::vector<double> pressure_pa;         // pre-roll + cycles (absolute pressure: the model input)
  std::vector<std::size_t> cycle_starts;   // indices into pressure_pa; cycles + 1 entries (the last is the end)
  std::vector<std::size_t> window_starts;  // per cycle kCrankWindows + 1 entries, flattened (c * (W + 1) + w)
  std::size_t data_start = 0;              // first frame after the pre-roll (= cycle_starts[0])
  std::size_t first_cycle = 0;             // index of this segment's first cycle in the condition's list
};

struct CycleInfo {
  double duration_s = 0.0;
  double speed_rpm = 0.0;  // from the duration (two revolutions per cycle)
};

struct ConditionData {
  ConditionInfo info;
  std::size_t mics = 0;
  std::size_t bands = 0;
  std::vector<CycleInfo> cycles;
  std::vector<PreparedSegment> segments;
  // Band mean squares (Pa^2), per cycle:
  std::vector<double> cpl_ms;      // [c * bands + b]  cylinder pressure
  std::vector<double> mic_ms;      // [(c * mics + m) * bands + b]
  std::vector<double> win_ms;      // [(c * W + w) * bands + b]  microphone average per crank window
  std::vector<double> cpl_win_ms;  // [(c * W + w) * bands + b]  cylinder pressure per crank window
  std::vector<double> win_frames;  // [c * W + w]
  // Coherence with the cylinder pressure across cycles (per band, microphone-averaged; NaN with < 4 cycles):
  std::vector<double> periodic_share;     // power of the cycle-synchronous average / total power
  std::vector<double> fluct_coherence;    // coherence of the cycle-to-cycle fluctuations with the pressure's
  std::vector<double> coherent_fraction;  // periodic + coherent fluctuating share: upper bound of what any
                                          // pressure-driven model can predict

  std::size_t cycle_count() const { return cycles.size(); }
  double mic_avg_ms(std::size_t c, std::size_t b) const;  // energy average over microphones
  double mean_speed_rpm() const;
};

struct DatasetOptions {
  std::size_t preroll_cycles = 4;
  std::size_t max_cycles = 0;  // per condition, 0 = all
  bool coherence = true;
};

struct BandDataset {
  std::vector<dsp::ThirdOctaveBand> bands;
  std::vector<ConditionData> conditions;
  std::vector<bool> line_free;  // per condition * bands: no cycle harmonic in the band (leakage only)

  std::size_t band_count() const { return bands.size(); }
  bool band_line_free(std::size_t condition, std::size_t band) const {
    return line_free[condition * bands.size() + band];
  }
};

// Cuts, prepares and measures one condition (all its recordings). Throws std::invalid_argument naming the
// condition when a recording holds no complete cycle with microphones.
ConditionData build_condition(const ConditionInfo& info, const std::vector<ConditionRecording>& recordings,
                              const DatasetOptions& options = {});

// Adds the per-band flags and the band list; conditions keep their order.
BandDataset make_dataset(std::vector<ConditionData> conditions);

// The bank pass shared by the measured and the re-simulated channels: runs `channels` interleaved signals
// laid out like `segment.pressure_pa` (constant offsets already removed) through a fresh bank over the pre-roll
// and the segment's first `cycles` cycles (0: all), and returns the mean square per cycle, channel and band
// ([(c * channels + ch) * bands + b]), and, when win_out is given, per cycle, crank window, channel and band
// ([((c * W + w) * channels + ch) * bands + b]). `signal` needs segment_frames(segment, cycles) frames.
void segment_band_powers(const PreparedSegment& segment, const double* signal, std::size_t channels, std::size_t cycles,
                         std::vector<double>& cycle_out, std::vector<double>* win_out = nullptr);

// Frames of the pre-roll and the first `cycles` cycles of a segment (0: all).
std::size_t segment_frames(const PreparedSegment& segment, std::size_t cycles = 0);
std::size_t segment_cycles(const PreparedSegment& segment);

}  // namespace noisemon::model::fit
