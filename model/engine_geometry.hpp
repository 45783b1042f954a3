// One cylinder's slider-crank geometry and the crank angle versus time: what the combustion metrics, the
// encoder decoders and the virtual engine share. Angles in degrees, 0 = firing TDC; a cycle spans [-360, 360).
#pragma once

#include <cstdint>
#include <vector>

namespace noisemon::model {

// Slider-crank geometry of one cylinder. Defaults: Yanmar L100V (bore 86 mm, stroke 75 mm, CR 21.2, 435 cc).
struct EngineGeometry {
  double bore_m = 0.086;
  double stroke_m = 0.075;
  double conrod_m = 0.118;
  double compression_ratio = 21.2;

  double piston_area_m2() const;
  double displacement_m3() const;      // Vd
  double clearance_volume_m3() const;  // Vc = Vd / (CR - 1)
  // Piston distance from its TDC position, m.
  double piston_travel_m(double theta_deg) const;
  double volume_m3(double theta_deg) const;
  double dvolume_m3_per_deg(double theta_deg) const;
  // Heat-transfer area: cylinder head + piston crown (each a bore disc) + liner over the clearance height and
  // the piston travel (Heywood, Internal Combustion Engine Fundamentals, ch. 2).
  double wall_area_m2(double theta_deg) const;
  double mean_piston_speed_m_s(double speed_rpm) const;

  bool operator==(const EngineGeometry&) const = default;
};

// Crank angle versus time: a mean speed with a once-per-cycle ripple, slowest at firing TDC (the single
// cylinder slows in compression and speeds up after firing):
//   phi(t) = theta0 + 6 n t                (mean angle, deg; n = mean speed, rpm)
//   theta  = phi - eps (360 / pi) sin(pi phi / 360),  so  dtheta/dt = 6 n (1 - eps cos(pi phi / 360)).
// Analytic, so independent threads compute the same theta(t); theta = phi at every cycle boundary.
//
// The mean speed may change in steps (an operating-point schedule): from step i on, phi = phi_i + 6 n_i (t - t_i).
// A step placed at a cycle boundary (phi_i = 720 k - 360) keeps theta continuous there, and the map phi -> theta does
// not depend on the speed, so time_s stays an exact inverse.
class CrankKinematics {
 public:
  struct SpeedStep {
    double t_s = 0.0;        // from this instant on
    double phi_deg = 0.0;    // the mean angle at t_s
    double speed_rpm = 0.0;  // the mean speed
  };

  CrankKinematics(double mean_speed_rpm, double speed_fluctuation, double theta0_deg = -360.0);
  // Steps in increasing time, each phi_deg where the previous step's speed brings the mean angle at its t_s.
  CrankKinematics(std::vector<SpeedStep> steps, double speed_fluctuation);

  double theta_deg(double t_s) const;     // unwrapped
  double speed_rpm(double t_s) const;     // instantaneous
  double time_s(double theta_deg) const;  // inverse of theta_deg (Newton on the monotone phi -> theta)

  // Cycle k spans unwrapped angles [720 k - 360, 720 k + 360).
  static std::int64_t cycle_index(double theta_deg);
  static double cycle_angle(double theta_deg);  // wrapped to [-360, 360)

 private:
  double mean_angle_deg(double t_s, const SpeedStep** step) const;

  std::vector<SpeedStep> steps_;
  double eps_;
};

}  // namespace noisemon::model
