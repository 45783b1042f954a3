#include "dsp/levels.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include "dsp/sound_power.hpp"

namespace noisemon::dsp {
namespace {

constexpr double kReferenceArea = 1.0;  // S0, m^2 (ISO 3744)

double energy_of(double level) { return std::pow(10.0, level / 10.0); }

}  // namespace

double level_db(double mean_square_pa2) {
  return 10.0 * std::log10(mean_square_pa2 / (kReferencePressurePa * kReferencePressurePa));
}

double mean_square_from_level(double level) { return kReferencePressurePa * kReferencePressurePa * energy_of(level); }

double energy_sum_db(std::span<const double> levels_db) {
  double e = 0;
  for (double l : levels_db) e += energy_of(l);
  return 10.0 * std::log10(e);  // -inf for no levels
}

double energy_average_db(std::span<const double> levels_db) {
  if (levels_db.empty()) return std::numeric_limits<double>::quiet_NaN();
  return energy_sum_db(levels_db) - 10.0 * std::log10(static_cast<double>(levels_db.size()));
}

double hemisphere_area_term_db(double radius_m) {
  return 10.0 * std::log10(hemisphere_area_m2(radius_m) / kReferenceArea);
}

double sound_power_level_db(double lp_db, double radius_m) { return lp_db + hemisphere_area_term_db(radius_m); }

double attenuation_db(double cpl_db, double spl_a_db) { return cpl_db - spl_a_db; }

}  // namespace noisemon::dsp
