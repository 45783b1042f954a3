// Sound power as ISO 3744 computes it, set up once per run: the microphones' area shares on the hemisphere, the
// check of their positions against the radius, the environmental correction K2 and the background band levels
// behind K1 (dsp/sound_power.hpp holds the standard's arithmetic; this holds what a run needs of it).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "drivers/source.hpp"
#include "dsp/sound_power.hpp"
#include "dsp/third_octave_bank.hpp"

namespace noisemon::daemon {

// [sound_power] of the configuration.
struct SoundPowerConfig {
  double k2_db = 0.0;               // environmental correction K2 (ISO 3744 Annex A): 0 in a hemi-anechoic cell
  double absorption_area_m2 = 0.0;  // > 0: K2 = 10 lg(1 + 4 S / A) from the room's absorption area instead
  // Background band levels (unweighted, dB re 20 uPa, energy mean over the microphones) at the nominal bands
  // 20 Hz ... 20 kHz, NaN where not measured; empty: no background, K1 = 0 and no band is judged against one.
  std::vector<double> background_db;
  double no_correction_above_db = dsp::kNoCorrectionAboveDb;  // ISO 3744:2010: 15 dB (the 1994 edition: 10 dB)
  double air_temperature_c = 23.0;  // during the test, for C1 and C2 (ISO 3744:2010 8.2.5); default: the
  double air_pressure_kpa = dsp::kReferenceStaticPressureKpa;  // reference atmosphere's, 23 deg C, 101.325 kPa
  bool full_range = false;          // LW(A) over every band of the overall levels; false: 100 Hz ... 10 kHz
  double source_dimension_m = 0.0;  // the source's characteristic dimension d0 for the surface check; 0: unknown
  // Each microphone's share of the surface (ISO 3744 eq. 13, S_i / S): empty and not voronoi: equal shares, as for
  // the standard's key positions and the thesis's Table 3.1 (each is the centre of an equal share by construction);
  // voronoi: each position's spherical-Voronoi cell, for positions laid out otherwise; or the shares themselves,
  // one per microphone (normalised to sum 1).
  bool voronoi_area_weights = false;
  std::vector<double> area_weights;
};

inline constexpr int kBackgroundBands = static_cast<int>(dsp::kThirdOctaveNominalHz.size());  // 20 Hz ... 20 kHz
// The nominal frequency of background band i (0: 20 Hz ... 30: 20 kHz), and the index of a nominal frequency.
double background_band_hz(int i);
int background_band_index(double nominal_hz);

class SoundPowerSetup {
 public:
  SoundPowerSetup(const SoundPowerConfig& config, const drivers::StreamInfo& info,
                  const std::vector<dsp::ThirdOctaveBand>& bands);

  // Each microphone's share of the hemisphere's area (SoundPowerConfig::area_weights). Throws std::invalid_argument
  // naming [sound_power] when configured shares do not match the microphones or the positions are not known.
  const std::vector<double>& area_weights() const { return weights_; }
  const dsp::SurfaceCheck& surface_check() const { return check_; }
  double k2_db() const { return k2_db_; }
  double c1_db() const { return c1_db_; }  // the meteorological corrections added to LW (ISO 3744:2010 8.2.5)
  double c2_db() const { return c2_db_; }
  // The nominal band range LW(A) is summed over: 100 Hz ... 10 kHz (ISO 3744:2010), or everything (full_range).
  double lw_low_hz() const { return lw_low_hz_; }
  double lw_high_hz() const { return lw_high_hz_; }
  bool in_lw_range(double nominal_hz) const { return nominal_hz >= lw_low_hz_ && nominal_hz <= lw_high_hz_; }
  double surface_term_db() const { return surface_term_db_; }  // 10 lg(S / S0), S = 2 pi r^2
  bool has_background() const { return has_background_; }
  double background_db(std::size_t band) const { return background_[band]; }
  // K1 of a band whose measured mean level (unweighted) is `level_db`; K1 = 0 (uncorrected) without a background
  // level for the band; 1.3 dB and an upper bound within 6 dB of it.
  dsp::BackgroundCorrection correction(std::size_t band, double level_db) const;
  // One line per problem of the surface and its positions ("mic3: 1.20 m from ..."), empty when none.
  std::vector<std::string> problems() const;

 private:
  std::vector<double> weights_;
  dsp::SurfaceCheck check_;
  double k2_db_ = 0.0, surface_term_db_ = 0.0, no_correction_above_db_ = dsp::kNoCorrectionAboveDb;
  double c1_db_ = 0.0, c2_db_ = 0.0, lw_low_hz_ = 0.0, lw_high_hz_ = 0.0;
  bool has_background_ = false;
  std::vector<double> background_;  // per processing band, NaN without one
};

}  // namespace noisemon::daemon
