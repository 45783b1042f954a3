// The time-domain re-simulation (simulate_condition, make_anchor) against the block's analytic steady-state response:
// the synthetic cell's microphone is the pressure's harmonics through eq. 4.13's frequency response, computed in
// tests/model/test_band_fit_cell.hpp without the project's integrator.
#include <gtest/gtest.h>

#include <cmath>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"
#include "tests/model/test_band_fit_cell.hpp"

namespace noisemon::model {
namespace {

using test_cell::db;

TEST(BandFitAnchor, ReSimulationOfTheTrueBlockMatchesTheAnalyticResponseInEveryScoredBand) {
  const BlockParams truth = preset("linear");
  const fit::BandDataset data = test_cell::block_dataset(truth, {test_cell::CellCondition{}});
  const fit::ConditionData& cond = data.conditions[0];
  std::vector<double> sim;
  fit::band_fit_internal::simulate_condition(cond, truth, 0, sim);
  ASSERT_EQ(sim.size(), cond.cycle_count() * data.band_count());
  const auto scored = test_cell::scored_bands(data);
  const std::vector<double> pred = test_cell::cycle_mean(sim, data.band_count());
  int checked = 0;
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    if (!scored[0][b]) continue;
    double meas = 0.0;
    for (std::size_t c = 0; c < cond.cycle_count(); ++c)
      meas += cond.mic_avg_ms(c, b) / static_cast<double>(cond.cycle_count());
    EXPECT_NEAR(db(meas / pred[b]), 0.0, 0.02) << data.bands[b].nominal_hz << " Hz";
    ++checked;
  }
  EXPECT_GT(checked, 20);
}

// The anchor's Jacobian d ln P_b / d ln theta (forward differences of re-simulations, step ln 1.03) against the same
// difference of the analytic band powers: sum over the cell's harmonics of the band's response times a^2 / 2 |H|^2.
TEST(BandFitAnchor, JacobianMatchesTheAnalyticBandPowers) {
  const BlockParams block = preset("linear");
  const test_cell::CellCondition cell;
  const fit::BandDataset data = test_cell::block_dataset(block, {cell});
  const std::vector<fit::BlockParam> params = {fit::BlockParam::kK1, fit::BlockParam::kB1, fit::BlockParam::kC0,
                                               fit::BlockParam::kC1};
  const fit::Anchor anchor = make_anchor(data, block, {0}, 8, false, params);
  ASSERT_EQ(anchor.jac.size(), 1u);
  const auto analytic_power = [&](const BlockParams& p, std::size_t b) {
    double sum = 0.0;
    const double f0 = cell.rpm / 120.0;
    for (std::size_t h = 1; h * f0 <= cell.max_hz; ++h) {
      const double f = static_cast<double>(h) * f0, a = cell.amplitude_pa / (1.0 + f / cell.corner_hz);
      sum += fit::band_fit_internal::band_power_response(data.bands[b], f) * a * a / 2 *
             std::norm(test_cell::block_response(p, f));
    }
    return sum;
  };
  const double h = std::log(1.03);
  const auto scored = test_cell::scored_bands(data);
  for (std::size_t b = 0; b < data.band_count(); ++b) {
    if (!scored[0][b]) continue;
    for (std::size_t i = 0; i < params.size(); ++i) {
      BlockParams stepped = block;
      fit::set_param(stepped, params[i], fit::param_value(block, params[i]) * 1.03);
      const double want = std::log(analytic_power(stepped, b) / analytic_power(block, b)) / h;
      EXPECT_NEAR(anchor.jac[0][b * params.size() + i], want, 0.01)
          << fit::param_name(params[i]) << " at " << data.bands[b].nominal_hz << " Hz";
    }
  }
}

}  // namespace
}  // namespace noisemon::model
