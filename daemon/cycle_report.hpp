// The per-cycle result inside the daemon: a plain struct that travels through a lock-free ring from the
// processing thread to the LCM thread, where it becomes a noisemon::cycle_report_t.
#pragma once

#include <cstdint>

#include "daemon/crank_windows.hpp"
#include "drivers/source.hpp"
#include "model/combustion_metrics.hpp"

namespace noisemon::daemon {

inline constexpr std::size_t kMaxBands = 32;
inline constexpr std::size_t kMaxMics = drivers::SampleBlock::kMaxChannels;

// Bits of CycleReport::band_flags, ::mic_flags and ::flags; the same values as the LCM constants in
// msgs/cycle_report_t.lcm (whose comments say what each one means).
enum BandFlag : std::int8_t {
  kBandNyquistCut = 1,
  kBandSlow = 2,
  kBandSettling = 4,
  kBandBelowFiring = 8,
  kBandPressurePassband = 16,
  kBandMicPassband = 32,
  kBandBackground = 64,  // 6 dB or less above the background (ISO 3744:2010): K1 1.3 dB, an upper bound
};
enum MicFlag : std::int8_t {
  kMicExcluded = 1,  // left out of the measured (array-average) levels of this cycle
  kMicFlat = 2,      // every sample of the cycle the same: a stuck converter
  kMicOverload = 4,  // a sample reached 0.99 of the converter's full scale
  kMicNan = 8,       // non-finite samples were replaced by 0 (in the cycle, or its filters still ring from them)
  kMicLow = 16,      // more than ProcessorConfig::mic_low_db below the median microphone level: unplugged?
};
enum CycleFlag : std::int32_t {
  kCycleSettling = 1,
  kCycleGap = 2,
  kCycleNoOperatingPoint = 4,
  kCycleLengthOdd = 8,
  kCycleNoMics = 16,          // pressure-only stream: measured levels and attenuation are NaN
  kCycleEncoder = 32,         // crank angle unknown in the cycle, or its start uncertain: combustion metrics NaN
  kCycleOverload = 64,        // the pressure or a microphone reached 0.99 of its converter's full scale
  kCycleMicExcluded = 128,    // a microphone was left out of the measured levels (see mic_flags)
  kCyclePressureFault = 256,  // pressure flat, overloaded or non-finite (or ringing from replaced samples):
                              // CPL, predictions, attenuation and combustion metrics are NaN
  kCycleLwUpperBound = 512,   // a band of the measured LW(A) is 6 dB or less above the background: an upper bound
  kCycleAngleGap = 1024,      // the crank-angle stream misses edges of this cycle: combustion metrics NaN
};

struct CycleReport {
  std::int64_t utime = 0;             // instant of the cycle's first frame (crank angle -360 deg)
  std::int64_t window_end_utime = 0;  // end of the cycle's acoustic window (for latency)
  std::int64_t cycle = 0;
  double duration_s = 0;
  drivers::OperatingPoint op;
  double lpa_measured_db = 0, lpa_predicted_db = 0;
  double lwa_measured_db = 0, lwa_predicted_db = 0;  // this cycle's, K1, K2, C1, C2 applied (ISO 3744:2010)
  double radius_m = 0;
  double k2_db = 0;                     // the environmental correction in lwa_*
  double c1_db = 0, c2_db = 0;          // the meteorological corrections in lwa_* (ISO 3744:2010)
  float lw_low_hz = 0, lw_high_hz = 0;  // the nominal band range lwa_* are summed over
  double combustion_noise_db =
      0;  // CPL through the thesis's fixed eq. 4.1 attenuation, A-weighted (model/combustion_noise)
  std::uint16_t nbands = 0;
  float band_hz[kMaxBands] = {};
  float spl_a_measured_db[kMaxBands] = {};
  float spl_a_predicted_db[kMaxBands] = {};
  float cpl_db[kMaxBands] = {};
  float att_measured_db[kMaxBands] = {};
  float att_predicted_db[kMaxBands] = {};
  std::int8_t band_flags[kMaxBands] = {};
  float k1_db[kMaxBands] = {};          // background correction of the measured band (0: none; 1.3: kBandBackground)
  float background_db[kMaxBands] = {};  // the background band level behind k1_db (unweighted; NaN: none)
  std::uint16_t nmics = 0;
  float mic_lpa_db[kMaxMics] = {};       // every microphone's own level, excluded ones included
  std::int8_t mic_flags[kMaxMics] = {};  // MicFlag bits
  // Per 90-degree crank window (daemon/crank_windows.hpp), the A-weighted level over the overall levels' bands of
  // the measured sound (as lpa_measured_db) and of the prediction; NaN: no frame in it, or no measurement.
  float window_lpa_measured_db[kCrankWindows] = {};
  float window_lpa_predicted_db[kCrankWindows] = {};
  std::int32_t flags = 0;
  float processing_ms = 0;
  std::int64_t input_ns = 0;            // steady clock when the cycle's last block reached the processing thread
  double tdc_deg = 0;                   // the encoder's angle of firing TDC the combustion metrics used ([combustion])
  model::CombustionMetrics combustion;  // from the pressure on a 0.25 deg grid; NaN unless the grid is complete and
                                        // the cycle has neither kCycleEncoder nor kCyclePressureFault
};

}  // namespace noisemon::daemon
