// The levels of a completed cycle (CycleProcessor's part that turns the bank's mean squares into the report): each
// microphone's level and which microphones count, the bands' flags, measured and predicted band and overall levels,
// sound power per ISO 3744, and the crank windows' levels.
#include <algorithm>
#include <cmath>
#include <limits>

#include "daemon/cycle_processor.hpp"
#include "dsp/levels.hpp"
#include "dsp/math_constants.hpp"
#include "dsp/resample.hpp"
#include "dsp/weighting.hpp"
#include "model/combustion_noise.hpp"

namespace noisemon::daemon {
namespace {}  // namespace

// Every microphone's own A-weighted level over the bands above the firing frequency.
void CycleProcessor::mic_levels(CycleReport& r) const {
  const std::size_t nb = bank_.band_count();
  const double firing_hz = 1.0 / r.duration_s;  // one firing per 720 deg
  for (std::size_t m = 0; m < mics_; ++m) {
    double sum = 0;
    for (std::size_t b = 0; b < nb; ++b)
      if (bank_.bands()[b].upper_edge_hz >= firing_hz) sum += mean_square_[(2 + m) * nb + b] * a_gain_[b];
    r.mic_lpa_db[m] = static_cast<float>(dsp::level_db(sum));
  }
}

// Marks the microphones far below the others (MIC_LOW) and leaves every faulty one out (MIC_EXCLUDED).
void CycleProcessor::select_mics(CycleReport& r) const {
  // The median of the levels of the microphones that are not otherwise faulty (their levels say nothing).
  double levels[kMaxMics];
  std::size_t n = 0;
  for (std::size_t m = 0; m < mics_; ++m)
    if ((r.mic_flags[m] & (kMicFlat | kMicOverload | kMicNan)) == 0) levels[n++] = r.mic_lpa_db[m];
  if (n > 0) {
    std::sort(levels, levels + n);
    const double median = n % 2 ? levels[n / 2] : 0.5 * (levels[n / 2 - 1] + levels[n / 2]);
    for (std::size_t m = 0; m < mics_; ++m)
      if (!(r.mic_lpa_db[m] >= median - config_.mic_low_db)) r.mic_flags[m] |= kMicLow;  // NaN counts as low
  }
  for (std::size_t m = 0; m < mics_; ++m)
    if (r.mic_flags[m] != 0) {
      r.mic_flags[m] |= kMicExcluded;
      r.flags |= kCycleMicExcluded;
    }
}

// The highest frequencies the streams carry in a cycle of this duration (infinite when the source does not say).
CycleProcessor::PassbandLimits CycleProcessor::passband_limits(double duration_s) const {
  PassbandLimits l;
  const double revolutions_per_s = 2.0 / duration_s;
  if (info_.pressure_edges_per_rev > 0)
    l.pressure_hz = dsp::crank_angle_passband_hz(info_.pressure_edges_per_rev * revolutions_per_s);
  if (info_.mic_passband_hz > 0) l.mic_hz = info_.mic_passband_hz;
  return l;
}

// The bands' own flags (not the background's: that needs the level).
std::int8_t CycleProcessor::band_flags(std::size_t b, double duration_s, double settled_s) const {
  const dsp::ThirdOctaveBand& band = bank_.bands()[b];
  const PassbandLimits limits = passband_limits(duration_s);
  std::int8_t f = 0;
  if (band.nyquist_cut) f |= kBandNyquistCut;
  if (band.response_time_s > duration_s) f |= kBandSlow;
  if (band.upper_edge_hz < 1.0 / duration_s) f |= kBandBelowFiring;  // one firing per 720 deg
  if (band.upper_edge_hz > limits.pressure_hz) f |= kBandPressurePassband;
  if (mics_ > 0 && band.upper_edge_hz > limits.mic_hz) f |= kBandMicPassband;
  if (band.response_time_s > settled_s) f |= kBandSettling;
  return f;
}

double CycleProcessor::measured_mean_square(const CycleReport& r, std::size_t b) const {
  const std::size_t nb = bank_.band_count();
  if (config_.time_average_mics) {
    bool any = false;
    for (std::size_t m = 0; m < mics_; ++m) any |= !(r.mic_flags[m] & kMicExcluded);
    return any ? mean_square_[(2 + mics_) * nb + b] : kNaN;
  }
  const std::vector<double>& weights = sound_power_.area_weights();
  double sum = 0, weight_sum = 0;
  for (std::size_t m = 0; m < mics_; ++m)
    if (!(r.mic_flags[m] & kMicExcluded)) {
      sum += weights[m] * mean_square_[(2 + m) * nb + b];
      weight_sum += weights[m];
    }
  // Without a microphone nothing was measured: NaN, never a number.
  return weight_sum > 0 ? sum / weight_sum : kNaN;
}

// The A-weighted levels of the measured sound (the microphones of the measured levels, as they are averaged) and of
// the prediction per crank window; NaN for a window without frames, and as the cycle's measured and predicted are.
void CycleProcessor::window_levels(CycleReport& r, bool pressure_fault) const {
  const std::vector<double>& weights = sound_power_.area_weights();
  for (std::size_t w = 0; w < kCrankWindows; ++w) {
    double sum = 0, weight_sum = 0;
    for (std::size_t m = 0; m < mics_; ++m)
      if (!(r.mic_flags[m] & kMicExcluded)) {
        sum += weights[m] * windows_.mean_square(w, 1 + m);
        weight_sum += weights[m];
      }
    r.window_lpa_measured_db[w] = static_cast<float>(weight_sum > 0 ? dsp::level_db(sum / weight_sum) : kNaN);
    r.window_lpa_predicted_db[w] =
        static_cast<float>(pressure_fault ? kNaN : dsp::level_db(windows_.mean_square(w, 0)));
  }
}

// Band levels, attenuation and overall levels; measured from the microphones not excluded (NaN without any),
// predicted and CPL NaN when the pressure is faulty. Sound power per ISO 3744:2010 over its band range (100 Hz ...
// 10 kHz unless [sound_power] full_range): the measured band less its K1 (1.3 dB within 6 dB of the background,
// which makes the cycle's LW(A) an upper bound), less K2, plus 10 lg(S / S0), C1 and C2.
void CycleProcessor::band_levels(CycleReport& r, double settled_s, bool pressure_fault) const {
  const std::size_t nb = bank_.band_count();
  const std::vector<double>& ms = mean_square_;
  constexpr std::int8_t kNotOverall = kBandBelowFiring | kBandPressurePassband | kBandMicPassband;
  double meas_sum = 0, pred_sum = 0, lw_meas_sum = 0, lw_pred_sum = 0;
  double overall_cpl[kMaxBands], overall_hz[kMaxBands];
  std::size_t overall_bands = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    const double aw = dsp::a_weighting_db(bank_.bands()[b].exact_mid_hz);
    const double cpl = pressure_fault ? kNaN : dsp::level_db(ms[0 * nb + b]);
    const double pred_a = pressure_fault ? kNaN : dsp::level_db(ms[1 * nb + b]) + aw;
    const double meas = dsp::level_db(measured_mean_square(r, b));
    const double meas_a = meas + aw;
    const dsp::BackgroundCorrection k1 = sound_power_.correction(b, meas);
    std::int8_t f = band_flags(b, r.duration_s, settled_s);
    if (k1.validity == dsp::BandValidity::kUpperBound && !std::isnan(meas)) f |= kBandBackground;
    if (f & kBandSettling) r.flags |= kCycleSettling;
    // Only the bands every stream carries and that have a per-cycle meaning make the overall levels, so that the
    // measured and predicted ones cover the same bands.
    if (!(f & kNotOverall)) {
      overall_cpl[overall_bands] = cpl;
      overall_hz[overall_bands++] = bank_.bands()[b].exact_mid_hz;
      meas_sum += dsp::mean_square_from_level(meas_a);
      pred_sum += dsp::mean_square_from_level(pred_a);
      if (sound_power_.in_lw_range(bank_.bands()[b].nominal_hz)) {
        lw_meas_sum += dsp::mean_square_from_level(meas_a - k1.k1_db);
        lw_pred_sum += dsp::mean_square_from_level(pred_a);
        if (f & kBandBackground) r.flags |= kCycleLwUpperBound;
      }
    }
    r.band_hz[b] = static_cast<float>(bank_.bands()[b].nominal_hz);
    r.cpl_db[b] = static_cast<float>(cpl);
    r.spl_a_measured_db[b] = static_cast<float>(meas_a);
    r.spl_a_predicted_db[b] = static_cast<float>(pred_a);
    r.att_measured_db[b] = static_cast<float>(dsp::attenuation_db(cpl, meas_a));
    r.att_predicted_db[b] = static_cast<float>(dsp::attenuation_db(cpl, pred_a));
    r.k1_db[b] = static_cast<float>(k1.k1_db);
    r.background_db[b] = static_cast<float>(sound_power_.background_db(b));
    r.band_flags[b] = f;
  }
  const bool measured = !std::isnan(measured_mean_square(r, 0));
  const double lw_term =
      sound_power_.surface_term_db() - sound_power_.k2_db() + sound_power_.c1_db() + sound_power_.c2_db();
  r.k2_db = sound_power_.k2_db();
  r.c1_db = sound_power_.c1_db();
  r.c2_db = sound_power_.c2_db();
  r.lw_low_hz = static_cast<float>(sound_power_.lw_low_hz());
  r.lw_high_hz = static_cast<float>(sound_power_.lw_high_hz());
  r.lpa_measured_db = measured ? dsp::level_db(meas_sum) : kNaN;
  r.lpa_predicted_db = pressure_fault ? kNaN : dsp::level_db(pred_sum);
  r.lwa_measured_db = measured ? dsp::level_db(lw_meas_sum) + lw_term : kNaN;
  r.lwa_predicted_db = pressure_fault ? kNaN : dsp::level_db(lw_pred_sum) + lw_term;
  r.combustion_noise_db = model::combustion_noise_level_db({overall_cpl, overall_bands}, {overall_hz, overall_bands},
                                                           model::cao2015_eq_4_1_attenuation());
}

}  // namespace noisemon::daemon
