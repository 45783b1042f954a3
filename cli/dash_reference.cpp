#include "cli/dash_reference.hpp"

#include <algorithm>
#include <cmath>

#include "dsp/third_octave_bank.hpp"
#include "dsp/weighting.hpp"
#include "model/block_params.hpp"

namespace noisemon::cli {
namespace {

// Mean of |H|^2 over [lo, hi] Hz (midpoint rule on a grid fine against the response's slowest change).
double band_mean_gain(const model::BlockParams& params, double lo_hz, double hi_hz) {
  constexpr int kPoints = 256;
  double sum = 0;
  for (int i = 0; i < kPoints; ++i)
    sum += std::norm(model::linear_response(params, lo_hz + (i + 0.5) * (hi_hz - lo_hz) / kPoints));
  return sum / kPoints;
}

}  // namespace

nlohmann::json linear_reference_json(double fs_hz) {
  const model::BlockParams params = model::preset("linear");
  nlohmann::json band_hz = nlohmann::json::array(), att_db = nlohmann::json::array();
  const dsp::ThirdOctaveBank bank(fs_hz, 1);
  for (const auto& band : bank.bands()) {
    const double hi_hz = std::min(band.upper_edge_hz, fs_hz / 2);
    const double spl_a_minus_cpl =
        10 * std::log10(band_mean_gain(params, band.lower_edge_hz, hi_hz)) + dsp::a_weighting_db(band.exact_mid_hz);
    band_hz.push_back(band.nominal_hz);
    att_db.push_back(-spl_a_minus_cpl);
  }
  return {{"preset", "linear"}, {"band_hz", band_hz}, {"att_db", att_db}};
}

}  // namespace noisemon::cli
