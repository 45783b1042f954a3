// Per-cycle combustion metrics from the cylinder pressure, as indicating systems report them (AVL IndiCom,
// Kistler KiBox, Dewesoft CA): peak pressure, maximum rate of pressure rise, IMEP, apparent heat release and its
// burn angles, ringing intensity.
//
// Sources: J. B. Heywood, Internal Combustion Engine Fundamentals (1988): the slider-crank volume (eq. 2.5),
// gross and net IMEP (sec. 2.4: gross over compression and expansion, net over the whole cycle), the single-zone
// apparent heat-release rate dQ/dtheta = g/(g-1) p dV/dtheta + 1/(g-1) V dp/dtheta (eq. 9.25); J. A. Eng,
// "Characterization of pressure waves in HCCI combustion", SAE 2002-01-2859: ringing intensity
// RI = (beta (dp/dt)max)^2 / (2 g pmax) sqrt(g R Tmax), beta = 0.05 ms.
#pragma once

#include <limits>
#include <span>
#include <vector>

#include "dsp/iir_design.hpp"
#include "model/engine_geometry.hpp"

namespace noisemon::model {

// Pegging: a piezoelectric transducer measures pressure changes; the cycle's absolute level is set from the cycle
// itself, one offset for the whole cycle (-360 ... 360), before any figure. Intake: the mean over
// peg_intake_deg +- peg_half_width_deg (intake BDC) is set to peg_intake_pa (the measured or configured manifold
// pressure). Polytropic: over the compression window [peg_poly_from_deg, peg_poly_to_deg] the offset that makes the
// pressure the closest K V^-n, with n fixed (peg_exponent) or fitted (NaN: 1.20 ... 1.45).
enum class Pegging { kNone, kIntake, kPolytropic };

struct MetricsOptions {
  // The encoder's angle of firing TDC (thermodynamic TDC: `noisemon tdc`): the cycle processor turns its crank-angle
  // grid by it before the figures, so that the volume they integrate against is the piston's. 0: the encoder's zero.
  double tdc_deg = 0.0;
  Pegging pegging = Pegging::kNone;
  double peg_intake_pa = 1.0e5;
  double peg_intake_deg = -180.0;
  double peg_half_width_deg = 10.0;
  double peg_poly_from_deg = -100.0, peg_poly_to_deg = -40.0;
  double peg_exponent = std::numeric_limits<double>::quiet_NaN();
  double gamma = 1.35;  // ratio of specific heats for the heat release (Heywood: 1.3 ... 1.35)
  // Or gamma of the gas temperature at each angle (the heat release only): T from the ideal gas law with the charge
  // trapped at ivc_deg at intake_temperature_k, gamma(T) = 1.338 - 6.0e-5 T + 1.0e-8 T^2 (Brunt, Rai and Emtage,
  // SAE 981052, for diesel combustion products and air). NaN heat release when the grid misses ivc_deg.
  bool gamma_of_temperature = false;
  double derivative_half_width_deg = 0.5;  // dp/dtheta: least-squares slope over +-this (a Savitzky-Golay derivative)
  double heat_release_from_deg = -60.0;    // the heat release integrates over [from, to] (deg re firing TDC)
  double heat_release_to_deg = 90.0;
  // dp/dtheta max in the combustion window [from, rise_to_deg]: from rise_from_deg when it is set, else from the
  // start of injection (-soi_deg_btdc, the cycle's), else (no injection known: motored, or unknown) from
  // heat_release_from_deg. Before the injection the steepest slope is the compression's, not combustion's.
  double rise_from_deg = std::numeric_limits<double>::quiet_NaN();
  double rise_to_deg = 60.0;
  double soi_deg_btdc = std::numeric_limits<double>::quiet_NaN();  // per cycle, set by the caller
  // The per-cycle polytropic exponents (a health check: TDC, thermal shock of the transducer), deg re firing TDC: the
  // compression before any injection and the expansion after the burn, before the exhaust valve opens.
  double compression_from_deg = -90.0, compression_to_deg = -40.0;
  double expansion_from_deg = 60.0, expansion_to_deg = 110.0;
  double ringing_beta_s = 0.05e-3;  // Eng's beta
  // MAPO (maximum amplitude of pressure oscillations, the knock figure of AVL IndiCom and Kistler KiBox): the largest
  // |p| of the pressure band-passed (Butterworth, 4th order, forward and backward: zero phase) to
  // [mapo_low_hz, mapo_high_hz] on the grid itself, within [mapo_from_deg, mapo_to_deg]. The grid's sample rate
  // follows the speed (360 / step edges a revolution); an upper edge above 0.45 of it is taken down to there, a
  // lower edge above 0.4 of it leaves MAPO NaN.
  double mapo_low_hz = 4000.0, mapo_high_hz = 20000.0;
  double mapo_from_deg = -20.0, mapo_to_deg = 90.0;
  double intake_temperature_k = 313.0;  // trapped charge at intake valve closing, for T_max
  double ivc_deg = -150.0;              // intake valve closing (deg re firing TDC)
};

// Every value NaN until computed (a cycle with a gap keeps them so).
struct CombustionMetrics {
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  double peak_pressure_pa = kUnknown, peak_angle_deg = kUnknown;
  double max_rise_pa_per_deg = kUnknown, max_rise_angle_deg = kUnknown;  // in the combustion window (MetricsOptions),
                                                                         // with derivative_half_width_deg's smoothing
  double max_rise_motored_pa_per_deg =
      kUnknown;  // beside it: the motored-equivalent slope at that angle, the
                 // compression's polytropic carried on (what the burn adds is the rest)
  double imep_gross_pa = kUnknown, imep_net_pa = kUnknown;  // NaN when the cycle misses more than 2 deg of
                                                            // -180 ... 180 (gross) or -360 ... 360 (net)
  double pmep_pa = kUnknown;  // pumping: net - gross (negative for a naturally aspirated engine)
  double n_compression = kUnknown, n_expansion = kUnknown;  // polytropic exponents (MetricsOptions' windows)
  double heat_release_j = kUnknown;                         // cumulative apparent heat release, minimum to maximum
  double ca05_deg = kUnknown, ca10_deg = kUnknown, ca50_deg = kUnknown,
         ca90_deg = kUnknown;                    // 5, 10, 50, 90 % of it
                                                 // (NaN without combustion)
  double burn_duration_deg = kUnknown;           // CA10 to CA90
  double ringing_intensity_w_per_m2 = kUnknown;  // NaN without the speed
  double mapo_pa = kUnknown;                     // NaN without the speed, or a band the grid cannot carry
  double pegging_offset_pa = kUnknown;           // added to the whole cycle before the figures (0: no pegging)
  double pegging_exponent = kUnknown;            // the polytropic pegging's n (fixed or fitted)
};

// Metrics of one cycle: pressure_pa[i] at crank angle first_deg + i * step_deg (0 = firing TDC); the whole
// cycle is -360 ... 360 deg. The geometry (model/engine_geometry.hpp) defaults to the Yanmar L100V of
// ../shared/data, which the virtual engine is too; its rod length (118 mm) is not published with the data.
// speed_rpm converts dp/dtheta to dp/dt for the ringing intensity. Throws std::invalid_argument naming what is
// wrong (geometry, step, too few samples).
CombustionMetrics combustion_metrics(std::span<const double> pressure_pa, double first_deg, double step_deg,
                                     const EngineGeometry& engine, double speed_rpm,
                                     const MetricsOptions& options = {});

// The metrics' scratch space: sized by the first call and reused, so a caller that keeps one (the processing
// thread) does not allocate per cycle. It also keeps the cylinder volume and its derivative at the grid's angles
// (their sines and cosines were most of the metrics' time), recomputed only when the grid or the geometry change.
struct MetricsWorkspace {
  std::vector<double> slope, heat, pegged, band;
  std::vector<dsp::Biquad> mapo_filter;  // designed for mapo_fs_hz (and the options' band); again when they move 1 %
  double mapo_fs_hz = 0.0, mapo_low_hz = 0.0, mapo_high_hz = 0.0;
  std::vector<double> volume_m3, dvolume_m3_per_deg;
  double volume_first_deg = 0.0, volume_step_deg = 0.0;
  EngineGeometry volume_engine;
};
CombustionMetrics combustion_metrics(std::span<const double> pressure_pa, double first_deg, double step_deg,
                                     const EngineGeometry& engine, double speed_rpm, const MetricsOptions& options,
                                     MetricsWorkspace& scratch);

}  // namespace noisemon::model
