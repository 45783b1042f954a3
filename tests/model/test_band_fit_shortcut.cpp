// The frequency-domain shortcut against the time-domain re-simulation (a second method) on a linear block: the band
// powers of a re-simulation at the anchor, moved by F_b(theta) / F_b(theta_anchor) (extension_factors, apply_factors),
// against a re-simulation at theta itself. Also the speed extension's frequency scaling (exactly a re-scaled block:
// H_theta(w / s) = H_theta'(w) with k1' = k1 s^2, b1' = b1 s, c0' = c0 s^2, c1' = c1 s) and the second mode's factor
// against the time-domain mode filter.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"
#include "tests/model/test_band_fit_cell.hpp"

namespace noisemon::model {
namespace {

using fit::band_fit_internal::condition_spectrum;
using fit::band_fit_internal::simulate_condition;
using test_cell::db;

constexpr std::size_t kCycles = 8;

struct ShortcutCell {
  fit::BandDataset data = test_cell::block_dataset(preset("linear"), {test_cell::CellCondition{}});
  fit::ConditionSpectrum spec = condition_spectrum(data, 0, kCycles);
  std::vector<std::vector<char>> scored = test_cell::scored_bands(data);
};

const ShortcutCell& cell() {
  static const ShortcutCell c;
  return c;
}

// Largest |difference| in dB over the scored bands of two per-cycle predictions.
double worst_db(const std::vector<double>& a, const std::vector<double>& b) {
  const ShortcutCell& c = cell();
  const std::size_t nb = c.data.band_count();
  const std::vector<double> ma = test_cell::cycle_mean(a, nb), mb = test_cell::cycle_mean(b, nb);
  double worst = 0.0;
  for (std::size_t band = 0; band < nb; ++band)
    if (c.scored[0][band]) worst = std::max(worst, std::abs(db(ma[band] / mb[band])));
  return worst;
}

// The anchor's re-simulation moved to `model` by the shortcut.
std::vector<double> shortcut(const BlockParams& anchor, const fit::ExtendedModel& model) {
  const ShortcutCell& c = cell();
  std::vector<double> moved;
  simulate_condition(c.data.conditions[0], anchor, kCycles, moved);
  fit::apply_factors(fit::extension_factors(c.data, 0, c.spec, anchor, model), c.data.conditions[0], moved, nullptr);
  return moved;
}

std::vector<double> resimulated(const BlockParams& block) {
  std::vector<double> out;
  simulate_condition(cell().data.conditions[0], block, kCycles, out);
  return out;
}

TEST(BandFitShortcut, MovesTheAnchorLikeATimeDomainReSimulationOfALinearBlock) {
  const BlockParams anchor = preset("linear");
  struct Step {
    const char* what;
    double k1, b1, c0, c1;
  };
  const Step steps[] = {{"k1 x 1.3", 1.3, 1, 1, 1},      {"k1 x 0.7", 0.7, 1, 1, 1}, {"b1 x 0.5", 1, 0.5, 1, 1},
                        {"b1 x 2", 1, 2, 1, 1},          {"c0 x 2", 1, 1, 2, 1},     {"c1 x 0.6", 1, 1, 1, 0.6},
                        {"all four", 1.2, 0.7, 1.5, 0.8}};
  for (const Step& s : steps) {
    fit::ExtendedModel m;
    m.block = anchor;
    m.block.k1 *= s.k1;
    m.block.b1 *= s.b1;
    m.block.c0 *= s.c0;
    m.block.c1 *= s.c1;
    const double moved = worst_db(shortcut(anchor, m), resimulated(anchor));
    const double err = worst_db(shortcut(anchor, m), resimulated(m.block));
    std::printf("%-10s moves the bands by up to %6.2f dB; shortcut vs re-simulation: %.4f dB\n", s.what, moved, err);
    EXPECT_LT(err, 0.05) << s.what;
  }
}

TEST(BandFitShortcut, SpeedExtensionIsARescaledBlockTimesItsGain) {
  const BlockParams anchor = preset("linear");
  fit::ExtendedModel m;
  m.block = anchor;
  m.on.speed = true;
  m.ext.speed_ref_rpm = 2000.0;  // the cell runs at 3000 rpm: 1 krpm above
  m.ext.speed_shift_per_krpm = 0.1;
  m.ext.speed_gain_db_per_krpm = 3.0;
  const double s = 1.1;
  BlockParams rescaled = anchor;
  rescaled.k1 *= s * s;
  rescaled.b1 *= s;
  rescaled.c0 *= s * s;
  rescaled.c1 *= s;
  std::vector<double> expected = resimulated(rescaled);
  for (double& x : expected) x *= std::pow(10.0, 0.3);
  const double err = worst_db(shortcut(anchor, m), expected);
  std::printf("speed: shortcut vs re-simulated rescaled block %.4f dB\n", err);
  EXPECT_LT(err, 0.05);
}

TEST(BandFitShortcut, SecondModeFactorMatchesTheTimeDomainModeFilter) {
  const BlockParams anchor = preset("linear");
  for (const auto& [mode_db, phase_deg] : {std::pair{6.0, 0.0}, {-6.0, 0.0}, {6.0, 90.0}, {10.0, -135.0}}) {
    fit::ExtendedModel m;
    m.block = anchor;
    m.on.second_mode = true;
    m.ext.mode_db = mode_db;
    m.ext.mode_hz = 1000.0;
    m.ext.mode_q = 4.0;
    m.ext.mode_phase_deg = phase_deg;
    // predict_condition runs the mode in the time domain (SecondModeFilter: two biquads); the shortcut as
    // |1 + a (cos(phi) R(f) - sin(phi) D(f))|^2 of the analog responses.
    const fit::ConditionPrediction time_domain = predict_condition(cell().data, 0, m, false, kCycles);
    const double err = worst_db(shortcut(anchor, m), time_domain.cycle_ms);
    const double moved = worst_db(time_domain.cycle_ms, resimulated(anchor));
    std::printf("mode %+.0f dB at %+.0f deg: moves the bands by up to %.2f dB; shortcut vs time domain %.4f dB\n",
                mode_db, phase_deg, moved, err);
    EXPECT_GT(moved, 3.0);
    EXPECT_LT(err, 0.1);
  }
}

}  // namespace
}  // namespace noisemon::model
