// Parameters of the engine-block structural attenuation model (thesis eq. 4.13, Table 4.1).
//   m z'' = u - k1 z - k3 z^3 - b1 z' - b3 z'^3,   y = C0 z + C1 z'
// u: cylinder pressure (Pa), y: sound pressure (Pa) at 1.75 m, energy-averaged over the microphones.
#pragma once

#include <complex>
#include <string>
#include <string_view>
#include <vector>

namespace noisemon::model {

struct BlockParams {
  double m = 1.0;       // kg
  double k1 = 9.87e8;   // N/m
  double k3 = 0.0;      // N/m^3
  double b1 = 2.20e4;   // N s/m
  double b3 = 0.0;      // N s^3/m^3
  double c0 = 7467.57;  // output gain on displacement
  double c1 = 11.885;   // output gain on velocity

  bool is_linear() const { return k3 == 0.0 && b3 == 0.0; }
};

// Table 4.1 presets: "linear", "nl_damper", "nl_spring_damper", "nl_spring_damper_opt".
std::vector<std::string> preset_names();
// Throws std::invalid_argument naming the preset and listing the valid ones.
BlockParams preset(std::string_view name);

// Eq. 4.1 with the thesis constants (ka = 11.885, wb = 2 pi 100, zeta = 0.35, wn = 2 pi 5000).
std::complex<double> thesis_tf_4_1(double f_hz);
// Frequency response of the linear part of eq. 4.13 (k3 = b3 = 0): (C1 s + C0) / (m s^2 + b1 s + k1).
std::complex<double> linear_response(const BlockParams& p, double f_hz);

}  // namespace noisemon::model
