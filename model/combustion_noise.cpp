#include "model/combustion_noise.hpp"
#include "dsp/math_constants.hpp"

#include <cmath>
#include <complex>
#include <limits>
#include <stdexcept>
#include <string>

#include "dsp/weighting.hpp"
#include "model/block_params.hpp"

namespace noisemon::model {
namespace {

// Table band 0 (nominal 20 Hz) is IEC 61260-1 band x = -17 re 1 kHz.
constexpr double kFirstBandIndex = -17.0;

// Position of f on the table's band axis: 0 at the 20 Hz band's exact mid frequency, 1 per 1/3 octave (base 10).
double band_position(double f_hz) { return 10.0 * std::log10(f_hz / 1000.0) - kFirstBandIndex; }

StructureAttenuation make_cao2015() {
  StructureAttenuation sa;
  for (std::size_t i = 0; i < kSaBandCount; ++i)
    sa.db[i] = -20.0 * std::log10(std::abs(thesis_tf_4_1(sa_band_exact_mid_hz(i))));
  sa.source =
      "Cao, J., Analysis and Simulation of Nonlinearities in Noise Attenuation Model for a Diesel Engine Block, "
      "MSME thesis, Purdue University, 2015, sec. 4.3.1, eq. (4.1), pp. 23-25: SA = -20 lg|ka(s+wb)/(s^2+2 zeta wn "
      "s+wn^2)|, ka = 11.885, wb = 2 pi 100, zeta = 0.35, wn = 2 pi 5000; engine-specific (Yanmar L70, 1.75 m), "
      "not the AVL/Lucas meter curve";
  return sa;
}

[[noreturn]] void throw_uncovered(double f_hz, const StructureAttenuation& sa) {
  throw std::invalid_argument("combustion_noise_level_db: band at " + std::to_string(f_hz) +
                              " Hz has no structure attenuation in the curve (" + sa.source + ")");
}

}  // namespace

double sa_band_exact_mid_hz(std::size_t band) {
  return 1000.0 * std::pow(10.0, (static_cast<double>(band) + kFirstBandIndex) / 10.0);
}

const StructureAttenuation& cao2015_eq_4_1_attenuation() {
  static const StructureAttenuation sa = make_cao2015();
  return sa;
}

double structure_attenuation_db(const StructureAttenuation& sa, double f_hz) {
  if (!std::isfinite(f_hz) || f_hz <= 0.0) return kNaN;
  const double last = static_cast<double>(kSaBandCount - 1);
  double p = band_position(f_hz);
  // The end bands hold their value across their own half band (out to the outer band edges), no further.
  if (p < -0.5 || p > last + 0.5) return kNaN;
  if (p < 0.0) p = 0.0;
  if (p > last) p = last;
  if (const double r = std::round(p); std::abs(p - r) < 1e-9) p = r;  // a mid-band frequency up to rounding
  const auto i = static_cast<std::size_t>(std::floor(p));
  if (i + 1 >= kSaBandCount) return sa.db[kSaBandCount - 1];
  const double t = p - static_cast<double>(i);
  if (t == 0.0) return sa.db[i];  // exact at a mid-band frequency, even beside a NaN neighbour
  return sa.db[i] + t * (sa.db[i + 1] - sa.db[i]);
}

double combustion_noise_level_db(std::span<const double> cpl_band_db, std::span<const double> band_hz,
                                 const StructureAttenuation& sa) {
  if (cpl_band_db.size() != band_hz.size())
    throw std::invalid_argument("combustion_noise_level_db: " + std::to_string(cpl_band_db.size()) +
                                " band levels but " + std::to_string(band_hz.size()) + " band frequencies");
  double energy = 0.0;
  bool any = false;
  for (std::size_t b = 0; b < cpl_band_db.size(); ++b) {
    if (std::isnan(cpl_band_db[b])) continue;
    const double att = structure_attenuation_db(sa, band_hz[b]);
    if (std::isnan(att)) throw_uncovered(band_hz[b], sa);
    energy += std::pow(10.0, (cpl_band_db[b] - att + dsp::a_weighting_db(band_hz[b])) / 10.0);
    any = true;
  }
  return any ? 10.0 * std::log10(energy) : kNaN;
}

}  // namespace noisemon::model
