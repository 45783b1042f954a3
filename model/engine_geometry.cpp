#include "model/engine_geometry.hpp"
#include "dsp/math_constants.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <utility>

namespace noisemon::model {

namespace {
constexpr double kDegToRad = kPi / 180.0;
}  // namespace

// ---------------------------------------------------------------------------------------------- geometry

double EngineGeometry::piston_area_m2() const { return 0.25 * kPi * bore_m * bore_m; }
double EngineGeometry::displacement_m3() const { return piston_area_m2() * stroke_m; }
double EngineGeometry::clearance_volume_m3() const { return displacement_m3() / (compression_ratio - 1.0); }

double EngineGeometry::piston_travel_m(double theta_deg) const {
  const double a = 0.5 * stroke_m;
  const double th = theta_deg * kDegToRad;
  const double s = std::sin(th);
  return conrod_m + a - (a * std::cos(th) + std::sqrt(conrod_m * conrod_m - a * a * s * s));
}

double EngineGeometry::volume_m3(double theta_deg) const {
  return clearance_volume_m3() + piston_area_m2() * piston_travel_m(theta_deg);
}

double EngineGeometry::dvolume_m3_per_deg(double theta_deg) const {
  const double a = 0.5 * stroke_m;
  const double th = theta_deg * kDegToRad;
  const double s = std::sin(th), c = std::cos(th);
  const double ds_dth = a * s * (1.0 + a * c / std::sqrt(conrod_m * conrod_m - a * a * s * s));
  return piston_area_m2() * ds_dth * kDegToRad;
}

double EngineGeometry::wall_area_m2(double theta_deg) const {
  return 2.0 * piston_area_m2() +
         kPi * bore_m * (piston_travel_m(theta_deg) + clearance_volume_m3() / piston_area_m2());
}

double EngineGeometry::mean_piston_speed_m_s(double speed_rpm) const { return 2.0 * stroke_m * speed_rpm / 60.0; }

// ---------------------------------------------------------------------------------------------- kinematics

CrankKinematics::CrankKinematics(double mean_speed_rpm, double speed_fluctuation, double theta0_deg)
    : CrankKinematics(std::vector<SpeedStep>{{0.0, theta0_deg, mean_speed_rpm}}, speed_fluctuation) {}

CrankKinematics::CrankKinematics(std::vector<SpeedStep> steps, double speed_fluctuation)
    : steps_(std::move(steps)), eps_(speed_fluctuation) {
  if (steps_.empty()) throw std::invalid_argument("CrankKinematics: no speed");
  for (std::size_t i = 0; i < steps_.size(); ++i) {
    if (!(steps_[i].speed_rpm > 0.0)) throw std::invalid_argument("CrankKinematics: mean speed must be positive");
    if (i > 0 && !(steps_[i].t_s > steps_[i - 1].t_s))
      throw std::invalid_argument("CrankKinematics: steps out of order");
  }
  if (!(speed_fluctuation >= 0.0 && speed_fluctuation < 0.5))
    throw std::invalid_argument("CrankKinematics: speed fluctuation must be in [0, 0.5)");
}

// The mean angle at t_s and the step in force then (the first step also before its instant).
double CrankKinematics::mean_angle_deg(double t_s, const SpeedStep** step) const {
  auto after =
      std::upper_bound(steps_.begin() + 1, steps_.end(), t_s, [](double t, const SpeedStep& s) { return t < s.t_s; });
  const SpeedStep& s = *(after - 1);
  *step = &s;
  return s.phi_deg + 6.0 * s.speed_rpm * (t_s - s.t_s);
}

double CrankKinematics::theta_deg(double t_s) const {
  const SpeedStep* s = nullptr;
  const double phi = mean_angle_deg(t_s, &s);
  return phi - eps_ * (360.0 / kPi) * std::sin(kPi / 360.0 * phi);
}

double CrankKinematics::speed_rpm(double t_s) const {
  const SpeedStep* s = nullptr;
  const double phi = mean_angle_deg(t_s, &s);
  return s->speed_rpm * (1.0 - eps_ * std::cos(kPi / 360.0 * phi));
}

double CrankKinematics::time_s(double theta_deg) const {
  // Solve phi - A sin(k phi) = theta (Kepler's equation; the map is monotone for eps < 1).
  const double k = kPi / 360.0, amp = eps_ / k;
  double phi = theta_deg;
  for (int it = 0; it < 20; ++it) {
    const double f = phi - amp * std::sin(k * phi) - theta_deg;
    const double step = f / (1.0 - eps_ * std::cos(k * phi));
    phi -= step;
    if (std::abs(step) <= 1e-13 * (1.0 + std::abs(phi))) break;
  }
  auto after = std::upper_bound(steps_.begin() + 1, steps_.end(), phi,
                                [](double p, const SpeedStep& s) { return p < s.phi_deg; });
  const SpeedStep& s = *(after - 1);
  return s.t_s + (phi - s.phi_deg) / (6.0 * s.speed_rpm);
}

std::int64_t CrankKinematics::cycle_index(double theta_deg) {
  return static_cast<std::int64_t>(std::floor((theta_deg + 360.0) / 720.0));
}

double CrankKinematics::cycle_angle(double theta_deg) {
  double w = theta_deg - 720.0 * std::floor((theta_deg + 360.0) / 720.0);
  if (w >= 360.0) w -= 720.0;  // rounding at the boundary
  return w;
}

}  // namespace noisemon::model
