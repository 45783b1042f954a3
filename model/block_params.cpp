#include "model/block_params.hpp"

#include <array>
#include <numbers>
#include <stdexcept>

namespace noisemon::model {
namespace {

struct NamedPreset {
  std::string_view name;
  double k1, k3, b1, b3;
};

// Thesis Table 4.1; m, C0 and C1 are common to all rows (BlockParams defaults, eq. 4.9).
constexpr std::array<NamedPreset, 4> kPresets{{
    {"linear", 9.87e8, 0.0, 2.20e4, 0.0},
    {"nl_damper", 9.87e8, 0.0, 7.00e3, 2.00e3},
    {"nl_spring_damper", 8.00e8, 1.00e13, 7.00e3, 2.00e3},
    {"nl_spring_damper_opt", 8.37e8, 1.00e13, 6.00e3, 4.00e3},
}};

// Eq. 4.1 constants.
constexpr double kKa = 11.885;
constexpr double kWb = 2.0 * std::numbers::pi * 100.0;
constexpr double kZeta = 0.35;
constexpr double kWn = 2.0 * std::numbers::pi * 5000.0;

}  // namespace

std::vector<std::string> preset_names() {
  std::vector<std::string> names;
  for (const auto& p : kPresets) names.emplace_back(p.name);
  return names;
}

BlockParams preset(std::string_view name) {
  for (const auto& p : kPresets) {
    if (p.name == name) {
      BlockParams out;
      out.k1 = p.k1;
      out.k3 = p.k3;
      out.b1 = p.b1;
      out.b3 = p.b3;
      return out;
    }
  }
  std::string msg = "unknown block-model preset '";
  msg.append(name).append("'; valid presets:");
  for (const auto& p : kPresets) msg.append(" ").append(p.name);
  throw std::invalid_argument(msg);
}

std::complex<double> thesis_tf_4_1(double f_hz) {
  const std::complex<double> s(0.0, 2.0 * std::numbers::pi * f_hz);
  return kKa * (s + kWb) / (s * s + 2.0 * kZeta * kWn * s + kWn * kWn);
}

std::complex<double> linear_response(const BlockParams& p, double f_hz) {
  const std::complex<double> s(0.0, 2.0 * std::numbers::pi * f_hz);
  return (p.c1 * s + p.c0) / (p.m * s * s + p.b1 * s + p.k1);
}

}  // namespace noisemon::model
