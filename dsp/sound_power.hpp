// Sound power over a hemispherical measurement surface above one reflecting plane, as ISO 3744:2010 computes it:
// the surface's key microphone positions, checks of the positions against the radius, the partial areas behind
// an energy average of unequally spaced microphones, the background correction K1 and the environmental
// correction K2, and the band power LW = Lp' - K1 - K2 + 10 lg(S / S0).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace noisemon::dsp {

using Position = std::array<double, 3>;  // x, y, z in m; z up from the reflecting plane, origin at the source centre

// ISO 3744:2010 Table B.2, the ten key positions for a broadband source (x/r, y/r, z/r), scaled to radius_m: three
// at z/r = 0.15, three at 0.45, three at 0.75 and one at the top, each at the centre of an equal share of the
// hemisphere's area (Archimedes: zones of equal height have equal area).
std::vector<Position> iso3744_key_positions(double radius_m);

// The share of the hemisphere's area (summing to 1) nearest to each position (its spherical Voronoi cell), for
// positions that are not associated with equal areas. Positions are taken as directions from the origin.
std::vector<double> hemisphere_area_weights(std::span<const Position> positions);

// What is wrong with a set of positions on a hemisphere of radius_m ("" for each that is fine, in order):
// below the reflecting plane, or farther than tolerance (a fraction of the radius) from the surface. The
// surface itself: radius under 1 m or under twice the source's characteristic dimension (ISO 3744 7.2.3; 0 = not
// known), fewer than ten positions (ISO 3744 8.1.1 for one reflecting plane).
struct SurfaceCheck {
  std::vector<std::string> surface;    // problems of the surface as a whole
  std::vector<std::string> positions;  // one per position, "" when it is fine
  bool ok() const;
};
SurfaceCheck check_hemisphere(std::span<const Position> positions, double radius_m, double source_dimension_m = 0.0,
                              double tolerance = 0.05);

// Energy average with weights that sum to 1: 10 lg(sum w_i 10^(L_i / 10)) (ISO 3744 eq. 13 with S_i / S = w_i).
double weighted_energy_average_db(std::span<const double> levels_db, std::span<const double> weights);

// A band's background correction K1 (ISO 3744:2010, 8.2.3): dL = level with the source - background level; above
// no_correction_above_db (15 dB) K1 = 0; above 6 dB K1 = -10 lg(1 - 10^(-dL / 10)); at 6 dB or less the background
// is too close for a correction to be trusted: K1 = 1.3 dB (the formula's value at 6 dB) and the band's power is an
// upper bound. (ISO 3744:1994 stopped correcting at 10 dB and had no upper bound: its bands under 6 dB were invalid.)
enum class BandValidity : std::uint8_t { kUncorrected = 0, kCorrected = 1, kUpperBound = 2 };
struct BackgroundCorrection {
  double k1_db = 0.0;
  BandValidity validity = BandValidity::kUncorrected;
};
inline constexpr double kMinBackgroundDifferenceDb = 6.0;
inline constexpr double kUpperBoundK1Db = 1.3;
inline constexpr double kNoCorrectionAboveDb = 15.0;
BackgroundCorrection background_correction(double level_with_source_db, double background_db,
                                           double no_correction_above_db = kNoCorrectionAboveDb);

// The meteorological corrections of ISO 3744:2010 (8.2.5), for the air's static pressure p_s (kPa) and temperature
// theta (deg C) during the test: C1 = -10 lg(p_s / p_s0) + 5 lg((273.15 + theta) / theta0), the reference quantity
// correction (the sound power's reference is 1 pW at the characteristic impedance of air at theta0 = 314 K), and
// C2 = -10 lg(p_s / p_s0) + 15 lg((273.15 + theta) / theta1), theta1 = 296 K, the radiation impedance correction to
// the reference atmosphere (p_s0 = 101.325 kPa, 23.0 deg C). At 23 deg C and 101.325 kPa: C1 = -0.13, C2 = +0.00 dB.
inline constexpr double kReferenceStaticPressureKpa = 101.325;
double reference_quantity_correction_c1_db(double temperature_c, double pressure_kpa);
double radiation_impedance_correction_c2_db(double temperature_c, double pressure_kpa);

// The frequency range of interest of ISO 3744:2010 for a broadband source: the one-third-octave bands 100 Hz ...
// 10 kHz (nominal), over which LW(A) is summed unless the full range is asked for.
inline constexpr double kIso3744LowestBandHz = 100.0, kIso3744HighestBandHz = 10000.0;

// Environmental correction K2 = 10 lg(1 + 4 S / A) (ISO 3744 eq. A.2): S the measurement surface, A the room's
// equivalent absorption area (m^2). 0 for a free field (A infinite).
double environmental_correction_k2_db(double surface_m2, double absorption_area_m2);

// Hemisphere area S = 2 pi r^2 (m^2).
double hemisphere_area_m2(double radius_m);

// LW = Lp' - K1 - K2 + 10 lg(S / S0), S0 = 1 m^2 (ISO 3744 eqs. 17, 18), before C1 + C2.
double band_sound_power_db(double mean_level_db, double k1_db, double k2_db, double surface_m2);

}  // namespace noisemon::dsp
