#include "daemon/sound_power_setup.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "dsp/levels.hpp"
#include "dsp/math_constants.hpp"

namespace noisemon::daemon {
namespace {}  // namespace

int background_band_index(double nominal_hz) {
  return static_cast<int>(std::lround(10.0 * std::log10(nominal_hz / 20.0)));
}

double background_band_hz(int i) { return dsp::kThirdOctaveNominalHz[static_cast<std::size_t>(i)]; }

SoundPowerSetup::SoundPowerSetup(const SoundPowerConfig& config, const drivers::StreamInfo& info,
                                 const std::vector<dsp::ThirdOctaveBand>& bands)
    : no_correction_above_db_(config.no_correction_above_db) {
  const std::size_t mics = info.mic_count;
  const bool positions_known = mics > 0 && info.mic_positions_m.size() == mics;
  if (positions_known) check_ = dsp::check_hemisphere(info.mic_positions_m, info.radius_m, config.source_dimension_m);
  weights_.assign(mics, mics > 0 ? 1.0 / static_cast<double>(mics) : 0.0);
  if (config.voronoi_area_weights) {
    if (!positions_known)
      throw std::invalid_argument(
          "[sound_power] area_weights = \"voronoi\": the source reports no microphone positions");
    weights_ = dsp::hemisphere_area_weights(info.mic_positions_m);
  } else if (!config.area_weights.empty()) {
    if (config.area_weights.size() != mics)
      throw std::invalid_argument("[sound_power] area_weights: " + std::to_string(config.area_weights.size()) +
                                  " shares for " + std::to_string(mics) + " microphones");
    double sum = 0;
    for (double w : config.area_weights) sum += w;
    for (std::size_t m = 0; m < mics; ++m) weights_[m] = config.area_weights[m] / sum;
  }
  const double surface_m2 = dsp::hemisphere_area_m2(info.radius_m);
  surface_term_db_ = dsp::hemisphere_area_term_db(info.radius_m);
  k2_db_ = config.absorption_area_m2 > 0 ? dsp::environmental_correction_k2_db(surface_m2, config.absorption_area_m2)
                                         : config.k2_db;
  c1_db_ = dsp::reference_quantity_correction_c1_db(config.air_temperature_c, config.air_pressure_kpa);
  c2_db_ = dsp::radiation_impedance_correction_c2_db(config.air_temperature_c, config.air_pressure_kpa);
  lw_low_hz_ = config.full_range ? 0.0 : dsp::kIso3744LowestBandHz;
  lw_high_hz_ = config.full_range ? std::numeric_limits<double>::infinity() : dsp::kIso3744HighestBandHz;
  background_.assign(bands.size(), kNaN);
  has_background_ = !config.background_db.empty();
  for (std::size_t b = 0; b < bands.size() && has_background_; ++b) {
    const int i = background_band_index(bands[b].nominal_hz);
    if (i >= 0 && i < static_cast<int>(config.background_db.size()))
      background_[b] = config.background_db[static_cast<std::size_t>(i)];
  }
}

dsp::BackgroundCorrection SoundPowerSetup::correction(std::size_t band, double level_db) const {
  if (std::isnan(background_[band])) return {};
  return dsp::background_correction(level_db, background_[band], no_correction_above_db_);
}

std::vector<std::string> SoundPowerSetup::problems() const {
  std::vector<std::string> out = check_.surface;
  for (std::size_t m = 0; m < check_.positions.size(); ++m)
    if (!check_.positions[m].empty()) out.push_back("mic" + std::to_string(m + 1) + ": " + check_.positions[m]);
  return out;
}

}  // namespace noisemon::daemon
