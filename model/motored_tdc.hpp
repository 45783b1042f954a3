// Thermodynamic TDC from motored cycles: where firing TDC lies on a recording's crank-angle scale, so that the
// volume the combustion figures integrate against is the piston's. A 1 deg error moves IMEP by several per cent
// (Pipitone & Beccari, SAE 2007-24-0052); an encoder's index mark is rarely set better than that.
//
// Two methods, reported side by side:
// - The motored peak plus a loss angle. Heat loss to the walls and blow-by make a motored cycle peak before TDC, by
//   the thermodynamic loss angle: 0.4 ... 1.3 deg measured on motored engines against a microwave TDC sensor
//   (KAIST dissertation, library.kaist.ac.kr bibCtrlNo 66913), the range Pipitone & Beccari report as well.
//   Default 0.7 deg, the middle of it; it depends on the engine and its speed, which is why the second method
//   is reported beside it.
// - A polytropic fit that needs no loss angle: over a window about the peak, ln(p - p0) = a - n ln V(theta - tdc)
//   - c theta, a polytropic compression and expansion whose losses (heat and blow-by, both growing with time) take
//   ln(p V^n) down linearly with the crank angle; the term c is what makes the fitted curve peak before its TDC.
//   tdc is scanned, then refined; a, n, c by linear least squares at each; p0 absorbs a pegging error.
#pragma once

#include <span>
#include <vector>

#include "model/engine_geometry.hpp"

namespace noisemon::model {

inline constexpr double kDefaultLossAngleDeg = 0.7;
inline constexpr double kMaxLossAngleDeg = 3.0;  // beyond this a loss angle is not a loss angle: refused

struct MotoredTdc {
  int cycles = 0;         // motored cycles averaged
  double peak_deg = 0.0;  // the mean motored cycle's peak, on the recording's scale
  double peak_bar = 0.0;
  double loss_angle_deg = kDefaultLossAngleDeg;
  double tdc_by_loss_angle_deg = 0.0;  // peak + loss angle: the TDC used
  double tdc_by_polytropic_deg = 0.0;  // the polytropic fit's
  double polytropic_exponent = 0.0;    // its n
  double fit_rms = 0.0;                // its rms residual in ln p
};

// cycles_bar: motored cycles on one uniform grid, angle first_deg + i * step_deg on the recording's scale (nominal
// TDC near 0). Throws std::invalid_argument naming what is wrong: no cycles, cycles of different lengths, a loss
// angle outside [0, kMaxLossAngleDeg], a peak farther than 10 deg from the nominal TDC (not a motored cycle, or a
// scale that is not about TDC), a grid that does not cover +-30 deg about the peak, a curve the polytropic fit does
// not follow within 2 % or with an exponent outside 1.05 ... 1.45 (a fired cycle).
MotoredTdc motored_tdc(std::span<const std::vector<double>> cycles_bar, double first_deg, double step_deg,
                       const EngineGeometry& engine, double loss_angle_deg = kDefaultLossAngleDeg);

}  // namespace noisemon::model
