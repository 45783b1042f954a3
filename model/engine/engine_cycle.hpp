// The virtual engine's physics: cylinder pressure of one four-stroke cycle from a single-zone model (geometry
// and crank kinematics: model/engine_geometry.hpp).
//
// Closed part (IVC..EVO): first law for a closed ideal-gas system integrated over crank angle with RK4,
//   m cv(T) dT/dtheta = dQhr/dtheta - dQht/dtheta - p dV/dtheta,   p = m R T / V,
// cv(T) = cv0 + cv1 T (air-like: gamma 1.40 at 300 K, about 1.31 at 2000 K), slider-crank V(theta),
// Woschni wall heat transfer, double-Wiebe heat release (premixed + diffusion). Start of combustion =
// SOI + ignition delay, found by a Livengood-Wu integral of the Hardenberg-Hase delay along the compression,
// so earlier injection sees colder, thinner charge, waits longer and burns a larger premixed fraction
// (Watson's correlation): faster pressure rise, louder (thesis 3.3: "early injection ... rapid rise in
// cylinder pressure ... increased noise").
// Open part: intake pressure until IVC; after EVO a smooth (C1) blowdown to the exhaust pressure and, over the
// last 20 deg, back to the intake pressure so consecutive cycles join continuously.
// On top of the single-zone pressure: the combustion-excited gas ringing of the cylinder's acoustic modes
// (model/engine/gas_ringing.hpp), in pressure_pa() (the true pressure); the closed-part traces and the summary's peak
// and rise are the single zone's.
//
// Angles in degrees, 0 = firing TDC; a cycle spans [-360, 360). Pressure absolute, Pa. SI units otherwise.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "model/engine/gas_ringing.hpp"
#include "model/engine_geometry.hpp"

namespace noisemon::model::engine {

struct EngineCycleParams {
  EngineGeometry geometry;
  // Gas exchange (naturally aspirated).
  double intake_pressure_pa = 1.0e5;    // absolute, also the pressure at IVC
  double intake_temperature_k = 330.0;  // charge temperature at IVC (intake air heated by walls and residuals)
  double exhaust_pressure_pa = 1.05e5;
  double ivc_deg = -150.0;     // intake valve closes 30 deg after BDC
  double evo_deg = 130.0;      // exhaust valve opens 50 deg before BDC
  double blowdown_deg = 35.0;  // width of the Gaussian blowdown decay after EVO
  // Gas: R and cv(T) = cv0 + cv1 T. cv1 = 0 with cv0 = R / (gamma - 1) gives a constant gamma.
  double gas_constant_j_kg_k = 287.0;
  double cv0_j_kg_k = 680.6;
  double cv1_j_kg_k2 = 0.1247;
  // Woschni heat transfer; scale 0 makes the cycle adiabatic.
  double wall_temperature_k = 450.0;
  double heat_transfer_scale = 1.0;
  // Fuel and combustion.
  double fuel_lhv_j_kg = 42.5e6;
  double combustion_efficiency = 0.98;
  double stoichiometric_afr = 14.5;
  double cetane_number = 48.0;
  // Fuelling is open loop, like an ECU fuel map: enough fuel for IMEP = BMEP(load) + FMEP(speed) at this
  // assumed gross indicated efficiency.
  double assumed_indicated_efficiency = 0.49;
  // Double Wiebe: x = 1 - exp(-a ((theta - soc) / duration)^(shape + 1)).
  double wiebe_a = 6.908;  // 99.9 % burnt at the end of the duration
  double premixed_duration_deg = 9.0;
  double premixed_shape = 2.0;
  double diffusion_duration_base_deg = 25.0;  // diffusion duration = base + per_phi * equivalence ratio
  double diffusion_duration_per_phi_deg = 60.0;
  double diffusion_shape = 0.9;
  // Integration step of the closed part (also the resolution of the pressure table).
  double step_deg = 0.05;
  // Gas ringing excited by the premixed burn (realistic by default; GasRingingParams::off(): none).
  GasRingingParams ringing;
};

struct OperatingCondition {
  double speed_rpm = 3050.0;
  double load_nm = 0.0;  // brake torque
  double soi_deg_btdc = 18.0;
  bool motored = false;  // no fuel
};

// Per-cycle random scaling of the heat release (fuel energy) and of the ignition delay, and the phases of the gas
// ringing's modes (where the charge auto-ignites first moves from cycle to cycle).
struct CycleVariation {
  double heat_release_scale = 1.0;
  double ignition_delay_scale = 1.0;
  std::array<double, kRingingModes> ringing_phase_rad{};
};
// Deterministic in (seed, cycle), so threads that evaluate the same cycle independently agree. Both scales are
// 1 + relative_sigma * N(0, 1) (independent draws, clipped to +-4 sigma); the ringing phases are uniform in
// [0, 2 pi) whatever relative_sigma.
CycleVariation draw_cycle_variation(std::uint64_t seed, std::int64_t cycle, double relative_sigma);

// Friction mean effective pressure, Pa (Chen-Flynn form with typical small-diesel constants).
double friction_mep_pa(const EngineGeometry& geometry, double speed_rpm);
// Injected fuel per cycle, kg (0 when motored).
double fuel_mass_per_cycle_kg(const EngineCycleParams& params, const OperatingCondition& op);

struct CycleSummary {
  double trapped_mass_kg = 0;
  double fuel_mass_kg = 0;   // including the cycle's heat-release scale
  double fuel_energy_j = 0;  // fuel_mass * LHV * combustion efficiency
  double equivalence_ratio = 0;
  double soi_deg = 0;  // start of injection (negative: BTDC)
  double soc_deg = 0;  // start of combustion; NaN when motored or no ignition
  double ignition_delay_deg = 0;
  double premixed_fraction = 0;
  double peak_pressure_pa = 0;
  double peak_pressure_deg = 0;
  double max_dp_dtheta_pa_per_deg = 0;
  double heat_release_j = 0;        // IVC..EVO
  double heat_loss_j = 0;           // IVC..EVO, to the walls
  double closed_work_j = 0;         // IVC..EVO, integral of p dV
  double imep_gross_pa = 0;         // compression + expansion strokes (-180..180)
  double imep_net_pa = 0;           // whole cycle
  double ringing_amplitude_pa = 0;  // gas ringing: peak of mode (1,0) (0: none)
};

// One engine cycle. The constructor allocates every table; compute() does not allocate.
class EngineCycle {
 public:
  explicit EngineCycle(const EngineCycleParams& params = {});

  void compute(const OperatingCondition& op, const CycleVariation& variation = {});

  // Cylinder pressure at a cycle-relative angle (clamped to [-360, 360]); cubic Hermite between table nodes.
  // The true pressure: the single zone plus the gas ringing.
  double pressure_pa(double theta_deg) const;
  // Speed of sound of the cylinder gas at a temperature (gamma from cv(T)): what the ringing's modes follow.
  double speed_of_sound_m_s(double temperature_k) const;
  const CycleSummary& summary() const { return summary_; }
  const EngineCycleParams& params() const { return params_; }

  // Closed-part traces of the single zone on the integration grid (IVC..EVO), for diagnostics and tests.
  std::span<const double> closed_angle_deg() const { return closed_angle_; }
  std::span<const double> closed_temperature_k() const { return closed_temperature_; }
  std::span<const double> closed_pressure_pa() const;
  std::span<const double> heat_release_rate_j_per_deg() const { return hrr_; }
  std::span<const double> heat_loss_rate_j_per_deg() const { return htr_; }
  // Specific internal energy of the gas, J/kg (zero at 0 K): the integral of cv(T).
  double internal_energy_j_kg(double temperature_k) const;

 private:
  struct Constants;
  struct Combustion;
  struct Rates;
  Rates rates(std::size_t half_step, double temperature_k, const Constants& k, const Combustion& c) const;
  Constants constants(const OperatingCondition& op, double trapped_mass_kg, double piston_speed_m_s) const;
  Combustion start_cycle(const OperatingCondition& op, const CycleVariation& variation, double trapped_mass_kg,
                         double piston_speed_m_s);
  void ignite(Combustion& c, double soc_deg, double deg_per_s);
  void integrate_closed_part(const Constants& k, Combustion& c);
  void fill_open_part();
  void summarise();
  void add_ringing(double deg_per_s, const CycleVariation& variation, const Combustion& c);

  EngineCycleParams params_;
  double h_ = 0.05;  // table and integration step, deg
  std::size_t ivc_node_ = 0, evo_node_ = 0, nodes_ = 0;
  // Geometry on the half-step grid of the whole cycle (index 2 i = node i), computed once: V, dV/dtheta, wall
  // area times V^-0.8 (Woschni's p^0.8 at fixed T), motored polytropic pressure ratio (V_ivc / V)^1.35.
  std::vector<double> vol_, dvol_, area_v08_, motored_ratio_;
  // Whole-cycle pressure table: node i at -360 + i h; single zone (p_) and with the gas ringing (pt_).
  std::vector<double> p_, dp_, pt_, dpt_, ring_scratch_;
  std::vector<double> closed_angle_, closed_temperature_, hrr_, htr_;
  CycleSummary summary_;
};

}  // namespace noisemon::model::engine
