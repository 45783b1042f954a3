// Sound and pressure levels: SPL/CPL re 20 uPa, energy sums and averages, the hemisphere term of sound power,
// attenuation (ISO 3744's corrections: dsp/sound_power.hpp).
#pragma once

#include <cstddef>
#include <span>

namespace noisemon::dsp {

inline constexpr double kReferencePressurePa = 20e-6;

// 10 log10(mean_square / p_ref^2); -inf for zero.
double level_db(double mean_square_pa2);
// Mean square that gives the level.
double mean_square_from_level(double level_db);
// Energy average: 10 log10(mean(10^(L/10))).
double energy_average_db(std::span<const double> levels_db);
// Energy sum (overall level from band levels): 10 log10(sum(10^(L/10))).
double energy_sum_db(std::span<const double> levels_db);
// ISO 3744 hemisphere over a reflecting plane: S = 2 pi r^2, S0 = 1 m^2, LW = Lp + 10 log10(S / S0).
double hemisphere_area_term_db(double radius_m);
double sound_power_level_db(double lp_db, double radius_m);
// Attenuation curve (thesis eq. 2.1): CPL(band) - SPL_A(band).
double attenuation_db(double cpl_db, double spl_a_db);

}  // namespace noisemon::dsp
