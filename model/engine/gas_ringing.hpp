// Combustion-excited gas ringing: the acoustic modes of the cylinder's gas, set ringing by the rapid premixed
// burn of a DI diesel (the "knock" of a diesel's combustion noise). Part of the TRUE cylinder pressure: the engine
// structure and the microphones hear it, the transducer measures it.
//
// Frequencies (Draper, "Pressure waves accompanying detonation in the internal combustion engine", J. Aero. Sci.
// 5 (1938); Heywood, Internal Combustion Engine Fundamentals, ch. 9.6): a cylindrical cavity of bore B rings at
//   f_mn = c alpha_mn / (pi B),   c = sqrt(gamma R T) of the gas,
// alpha_10 = 1.841 (first circumferential), alpha_20 = 3.054 (second circumferential), alpha_01 = 3.832 (first
// radial): about 4.5-5.8 kHz, 7.4-9.6 kHz and 9.3-12 kHz in the 86 mm Yanmar bore at 1100-1900 K. T is the
// single-zone temperature, so the frequencies follow sqrt(T) as the gas heats in the burn and cools in the
// expansion (the real fired Yanmar record rings at 5.7 kHz in the 20 deg after TDC, the sim at its condition at
// 5.35 kHz: tests/model/test_engine_cycle).
//
// Excitation and amplitude: the envelope is the premixed heat-release rate (normalised to a peak of 1) through a
// first-order decay of time constant decay_s (~1 ms: the ringing dies within 1-3 ms), normalised to a peak of 1;
// mode (1,0) peaks at
//   A = gain_s * (dp/dt)_premixed,  (dp/dt)_premixed = (gamma - 1) / V * peak premixed heat-release rate (J/s)
// at the premixed peak, the pressure-rise rate the premixed burn alone would cause; the other modes at
// mode_weights times A. Eng's ringing intensity (J. A. Eng, "Characterization of pressure waves in HCCI
// combustion", SAE 2002-01-2859) has the same form with gain 50 us for a whole charge auto-igniting; a diesel's
// premixed part is a fraction of the charge, and gain_s = 6 us gives A = 0.28 bar (all modes together about
// 0.4-0.45 bar peak) in the thesis's idle cycles and A = 0.57 bar (0.8-1 bar peak with all modes, as their phases
// fall) for the strongest premixed burn (full load, SOI 24), as DI diesels ring (a few tenths of a bar to about a
// bar). The real fired Yanmar record
// (18 N m, 1800 rpm) carries about 0.2 bar at 5-6 kHz just after TDC; the sim at that condition: A = 0.24 bar.
// Each mode has a random phase per cycle (the auto-ignition site moves from cycle to cycle: CycleVariation).
// Motored cycles (no fuel) and cycles that never ignite do not ring. A raised-cosine taper over the last 20 deg
// before EVO ends it smoothly (it has decayed by then: e^-7 at 3050 rpm).
#pragma once

#include <array>
#include <cstddef>
#include <span>

namespace noisemon::model::engine {

inline constexpr std::size_t kRingingModes = 3;
// Bessel-function roots alpha_mn of the modes (1,0), (2,0), (0,1) (Draper 1938).
inline constexpr std::array<double, kRingingModes> kDraperAlpha{1.841, 3.054, 3.832};

struct GasRingingParams {
  double gain_s = 6e-6;     // mode (1,0) peak = gain_s * premixed pressure-rise rate (Pa/s); 0: no ringing
  double decay_s = 1.0e-3;  // time constant of the envelope's decay
  std::array<double, kRingingModes> mode_weights{1.0, 0.5, 0.3};  // (1,0), (2,0), (0,1) relative to A

  static GasRingingParams off() {
    GasRingingParams p;
    p.gain_s = 0.0;
    return p;
  }
  bool active() const { return gain_s > 0.0; }
};

// f_mn = c alpha / (pi B).
double draper_frequency_hz(double alpha, double speed_of_sound_m_s, double bore_m);
// Speed of sound of an ideal gas with cv(T) = cv0 + cv1 T: sqrt(gamma R T), gamma = (cv + R) / cv.
double gas_speed_of_sound_m_s(double temperature_k, double gas_constant_j_kg_k, double cv0_j_kg_k, double cv1_j_kg_k2);

// What the ringing of one cycle is computed from (the closed part of the single-zone cycle, on its grid).
struct RingingInput {
  std::span<const double> angle_deg;      // closed-part grid, uniform step
  std::span<const double> temperature_k;  // single-zone temperature on that grid
  double deg_per_s = 0.0;                 // crank speed
  double soc_deg = 0.0;                   // start of combustion
  double premixed_j = 0.0;                // premixed heat (double Wiebe's first part)
  double premixed_duration_deg = 1.0;
  double wiebe_a = 6.908;
  double premixed_shape = 2.0;
  double volume_at_peak_m3 = 0.0;  // cylinder volume at the premixed peak (soc + x* duration)
  double bore_m = 0.086;
  double gas_constant = 287.0, cv0 = 680.6, cv1 = 0.1247;
  std::array<double, kRingingModes> phase_rad{};
};

// Angle of the premixed Wiebe peak relative to soc, in units of the duration: x* = (m / ((m + 1) a))^(1/(m+1)).
double premixed_peak_fraction(double wiebe_a, double shape);

// Adds the ringing to p (Pa) and its derivative to dp (Pa/deg), both on in.angle_deg's grid; returns the mode
// (1,0) peak amplitude A (Pa), 0 when inactive or without premixed heat. scratch: 2 n doubles (no allocation).
double add_gas_ringing(const GasRingingParams& params, const RingingInput& in, std::span<double> p,
                       std::span<double> dp, std::span<double> scratch);

}  // namespace noisemon::model::engine
