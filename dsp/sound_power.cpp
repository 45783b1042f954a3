#include "dsp/sound_power.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace noisemon::dsp {
namespace {

constexpr double kReferenceAreaM2 = 1.0;   // S0
constexpr double kMinRadiusM = 1.0;        // ISO 3744 7.2.3
constexpr std::size_t kMinPositions = 10;  // ISO 3744 8.1.1, one reflecting plane
// Points of the quasi-uniform lattice that partitions the hemisphere: shares come out within about 1e-3.
constexpr int kLatticePoints = 40000;

// ISO 3744:2010 Table B.2, positions 1 to 10 (x/r, y/r, z/r).
constexpr std::array<Position, 10> kTableB2 = {{{-0.99, 0.00, 0.15},
                                                {0.50, -0.86, 0.15},
                                                {0.50, 0.86, 0.15},
                                                {-0.45, 0.77, 0.45},
                                                {-0.45, -0.77, 0.45},
                                                {0.89, 0.00, 0.45},
                                                {0.33, 0.57, 0.75},
                                                {-0.66, 0.00, 0.75},
                                                {0.33, -0.57, 0.75},
                                                {0.00, 0.00, 1.00}}};

double norm(const Position& p) { return std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]); }

template <class... Numbers>
std::string format(const char* pattern, Numbers... numbers) {
  char text[160];
  std::snprintf(text, sizeof text, pattern, static_cast<double>(numbers)...);
  return text;
}

}  // namespace

bool SurfaceCheck::ok() const {
  if (!surface.empty()) return false;
  for (const std::string& p : positions)
    if (!p.empty()) return false;
  return true;
}

std::vector<Position> iso3744_key_positions(double radius_m) {
  std::vector<Position> out;
  for (const Position& unit : kTableB2) out.push_back({unit[0] * radius_m, unit[1] * radius_m, unit[2] * radius_m});
  return out;
}

std::vector<double> hemisphere_area_weights(std::span<const Position> positions) {
  std::vector<Position> directions;
  for (const Position& p : positions) {
    const double n = norm(p);
    if (!(n > 0.0)) throw std::invalid_argument("hemisphere_area_weights: a position at the origin has no direction");
    directions.push_back({p[0] / n, p[1] / n, p[2] / n});
  }
  std::vector<double> weights(positions.size(), 0.0);
  // Fibonacci lattice: z uniform in (0, 1) is uniform in area on the hemisphere; the golden angle spreads azimuths.
  const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < kLatticePoints; ++i) {
    const double z = (i + 0.5) / kLatticePoints;
    const double rho = std::sqrt(1.0 - z * z);
    const double x = rho * std::cos(golden_angle * i), y = rho * std::sin(golden_angle * i);
    std::size_t nearest = 0;
    double best = -2.0;
    for (std::size_t k = 0; k < directions.size(); ++k) {
      const double cosine = x * directions[k][0] + y * directions[k][1] + z * directions[k][2];
      if (cosine > best) best = cosine, nearest = k;
    }
    if (!directions.empty()) weights[nearest] += 1.0 / kLatticePoints;
  }
  return weights;
}

SurfaceCheck check_hemisphere(std::span<const Position> positions, double radius_m, double source_dimension_m,
                              double tolerance) {
  SurfaceCheck check;
  if (!(radius_m >= kMinRadiusM))
    check.surface.push_back(format("radius %.2f m is under %.0f m", radius_m, kMinRadiusM));
  if (source_dimension_m > 0.0 && radius_m < 2.0 * source_dimension_m)
    check.surface.push_back(
        format("radius %.2f m is under twice the source's dimension %.2f m", radius_m, source_dimension_m));
  if (positions.size() < kMinPositions)
    check.surface.push_back(
        format("%.0f positions, fewer than the %.0f a hemisphere needs", positions.size(), kMinPositions));
  for (const Position& p : positions) {
    const double distance = norm(p);
    if (p[2] < 0.0)
      check.positions.push_back(format("below the reflecting plane (z = %.2f m)", p[2]));
    else if (!(std::abs(distance - radius_m) <= tolerance * radius_m))
      check.positions.push_back(
          format("%.2f m from the source centre, not on the %.2f m hemisphere", distance, radius_m));
    else
      check.positions.emplace_back();
  }
  return check;
}

double weighted_energy_average_db(std::span<const double> levels_db, std::span<const double> weights) {
  if (levels_db.size() != weights.size() || levels_db.empty()) return std::numeric_limits<double>::quiet_NaN();
  double energy = 0.0;
  for (std::size_t i = 0; i < levels_db.size(); ++i) energy += weights[i] * std::pow(10.0, levels_db[i] / 10.0);
  return 10.0 * std::log10(energy);
}

BackgroundCorrection background_correction(double level_with_source_db, double background_db,
                                           double no_correction_above_db) {
  const double difference = level_with_source_db - background_db;
  if (std::isnan(difference)) return {std::numeric_limits<double>::quiet_NaN(), BandValidity::kUpperBound};
  if (!(difference > kMinBackgroundDifferenceDb)) return {kUpperBoundK1Db, BandValidity::kUpperBound};
  if (difference > no_correction_above_db) return {0.0, BandValidity::kUncorrected};
  return {-10.0 * std::log10(1.0 - std::pow(10.0, -0.1 * difference)), BandValidity::kCorrected};
}

double reference_quantity_correction_c1_db(double temperature_c, double pressure_kpa) {
  return -10.0 * std::log10(pressure_kpa / kReferenceStaticPressureKpa) +
         5.0 * std::log10((273.15 + temperature_c) / 314.0);
}

double radiation_impedance_correction_c2_db(double temperature_c, double pressure_kpa) {
  return -10.0 * std::log10(pressure_kpa / kReferenceStaticPressureKpa) +
         15.0 * std::log10((273.15 + temperature_c) / 296.0);
}

double environmental_correction_k2_db(double surface_m2, double absorption_area_m2) {
  if (std::isinf(absorption_area_m2)) return 0.0;
  return 10.0 * std::log10(1.0 + 4.0 * surface_m2 / absorption_area_m2);
}

double hemisphere_area_m2(double radius_m) { return 2.0 * std::numbers::pi * radius_m * radius_m; }

double band_sound_power_db(double mean_level_db, double k1_db, double k2_db, double surface_m2) {
  return mean_level_db - k1_db - k2_db + 10.0 * std::log10(surface_m2 / kReferenceAreaM2);
}

}  // namespace noisemon::dsp
