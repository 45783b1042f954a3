// The residuals of the surrogate (condition_residuals, refit_on_anchor's figures): they vanish when the data is made by
// the parameters they are evaluated at (the microphone computed from the block's analytic response), stay near zero
// when the anchor sits elsewhere (the shortcut carries the difference), equal -10 log10(4) in every band for a block
// whose output gains are doubled, and their Jet derivatives agree with central differences.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "model/fit/band_fit.hpp"
#include "model/fit/band_fit_internal.hpp"
#include "tests/model/test_band_fit_cell.hpp"

namespace noisemon::model {
namespace {

namespace bfi = fit::band_fit_internal;

const BlockParams& residual_truth() {
  static const BlockParams p = [] {
    BlockParams q = preset("linear");
    q.k1 *= 1.2;
    q.b1 *= 1.5;
    return q;
  }();
  return p;
}

const fit::BandDataset& data() {
  static const fit::BandDataset d = [] {
    test_cell::CellCondition slow, fast;
    slow.name = "slow";
    slow.rpm = 2400.0;
    slow.corner_hz = 300.0;
    fast.name = "fast";
    fast.rpm = 3200.0;
    fast.seed = 2;
    return test_cell::block_dataset(residual_truth(), {slow, fast});
  }();
  return d;
}

fit::FitSetup setup() {
  fit::FitSetup s;
  s.data = &data();
  s.train = {0, 1};
  s.scored = test_cell::scored_bands(data());
  s.free = {fit::BlockParam::kK1, fit::BlockParam::kB1, fit::BlockParam::kC0, fit::BlockParam::kC1};
  s.evaluate_only = true;
  return s;
}

fit::FitOutcome evaluate(const BlockParams& anchor_block, const BlockParams& at) {
  const fit::FitSetup s = setup();
  const fit::Anchor anchor = make_anchor(data(), anchor_block, s.train, s.fit_cycles, false);
  fit::ExtendedModel m;
  m.block = at;
  return fit::refit_on_anchor(s, anchor, m);
}

TEST(BandFitResiduals, VanishWhenTheDataIsMadeByTheParametersTheyAreEvaluatedAt) {
  const fit::FitOutcome o = evaluate(residual_truth(), residual_truth());
  std::printf("at the truth: train RMS %.5f dB, objective %.3g\n", o.train_rms_db, o.objective);
  EXPECT_LT(o.train_rms_db, 0.01);
}

TEST(BandFitResiduals, StayNearZeroWhenTheAnchorIsElsewhere) {
  BlockParams away = residual_truth();
  away.k1 *= 0.8;
  away.b1 *= 1.3;
  away.c1 *= 0.8;
  const fit::FitOutcome there = evaluate(away, away);
  const fit::FitOutcome moved = evaluate(away, residual_truth());
  std::printf("anchor away: %.3f dB at the anchor, %.5f dB moved to the truth by the shortcut\n", there.train_rms_db,
              moved.train_rms_db);
  EXPECT_GT(there.train_rms_db, 1.0);
  EXPECT_LT(moved.train_rms_db, 0.03);
}

// The surrogate problem of the training conditions on an anchor, built by the fit's own layout functions.
struct Problem {
  fit::FitSetup s = setup();
  fit::Anchor anchor;
  bfi::Layout L;
  std::vector<bfi::CondSetup> conds;
  bfi::Values v;

  Problem(const BlockParams& at, const fit::ExtensionSet& on, bool windows) {
    s.extensions = on;
    anchor = fit::make_anchor(data(), residual_truth(), s.train, s.fit_cycles, windows);
    fit::ExtendedModel m;
    m.block = at;
    m.on = on;
    L = bfi::make_layout(data(), residual_truth(), at, s.free, false, on, s.train, s.scored);
    for (std::size_t i = 0; i < s.train.size(); ++i)
      conds.push_back(bfi::make_cond_setup(data(), anchor, i, L, s, m, 3000.0));
    v = bfi::initial_values(L, m, conds);
  }
};

TEST(BandFitResiduals, DoubledOutputGainsAreMinusSixDbInEveryBand) {
  BlockParams loud = residual_truth();
  loud.c0 *= 2.0;
  loud.c1 *= 2.0;
  const Problem p(loud, fit::ExtensionSet{}, false);
  const double expected = -10.0 * std::log10(4.0);
  for (const bfi::CondSetup& c : p.conds) {
    ASSERT_GT(c.bands.size(), 20u);
    bfi::CondResiduals r;
    bfi::condition_residuals(p.L, p.v, c, false, r);
    ASSERT_EQ(r.r.size(), c.bands.size());
    for (std::size_t i = 0; i < c.bands.size(); ++i)
      EXPECT_NEAR(r.r[i].a / c.weight, expected, 0.01) << data().bands[c.bands[i]].nominal_hz << " Hz";
  }
}

TEST(BandFitResiduals, JetDerivativesAgreeWithCentralDifferences) {
  fit::ExtensionSet on;
  on.second_mode = on.speed = on.stationary = on.locked = true;
  Problem p(residual_truth(), on, true);
  p.v.lin = {0.1, -0.2, 0.05, 0.1};
  p.v.mode = {4.0, std::log(1.5), std::log(3.0)};
  p.v.speed = {2.0, 0.05};
  p.v.lexp = {1.5};
  // Each structural variable: where it sits in Values.
  struct Var {
    const char* name;
    double* value;
    int index;
  };
  const Var vars[] = {{"k1", &p.v.lin[0], bfi::kSK1},
                      {"b1", &p.v.lin[1], bfi::kSB1},
                      {"c0", &p.v.lin[2], bfi::kSC0},
                      {"c1", &p.v.lin[3], bfi::kSC1},
                      {"mode dB", &p.v.mode[0], bfi::kSModeDb},
                      {"mode f", &p.v.mode[1], bfi::kSModeLogF},
                      {"mode Q", &p.v.mode[2], bfi::kSModeLogQ},
                      {"speed gain", &p.v.speed[0], bfi::kSSpeedGain},
                      {"speed shift", &p.v.speed[1], bfi::kSSpeedShift},
                      {"locked exp", &p.v.lexp[0], bfi::kSLockExp}};
  int windowed = 0;
  for (const bfi::CondSetup& c : p.conds) {
    windowed += static_cast<int>(c.wbands.size());
    bfi::CondResiduals jets;
    bfi::condition_residuals(p.L, p.v, c, true, jets);
    for (const Var& var : vars) {
      const double h = 1e-5, x = *var.value;
      bfi::CondResiduals plus, minus;
      *var.value = x + h;
      bfi::condition_residuals(p.L, p.v, c, false, plus);
      *var.value = x - h;
      bfi::condition_residuals(p.L, p.v, c, false, minus);
      *var.value = x;
      for (std::size_t i = 0; i < jets.r.size(); ++i) {
        const double numeric = (plus.r[i].a - minus.r[i].a) / (2 * h);
        EXPECT_NEAR(jets.r[i].v[var.index], numeric, 1e-5 + 1e-4 * std::abs(numeric)) << var.name << " residual " << i;
      }
    }
    // The additive noise's parameters: the prediction's derivative with respect to the stationary log parameter.
    for (std::size_t i = 0; i < jets.r.size(); ++i) {
      const std::size_t slot = jets.add_index[i];
      if (slot == std::string::npos) continue;
      const double h = 1e-5, x = p.v.stat[slot];
      bfi::CondResiduals plus, minus;
      p.v.stat[slot] = x + h;
      bfi::condition_residuals(p.L, p.v, c, false, plus);
      p.v.stat[slot] = x - h;
      bfi::condition_residuals(p.L, p.v, c, false, minus);
      p.v.stat[slot] = x;
      const double numeric = (plus.pred[i] - minus.pred[i]) / (2 * h);
      EXPECT_NEAR(jets.dpred_add[i], numeric, 1e-6 * std::abs(numeric) + 1e-300) << "residual " << i;
    }
  }
  EXPECT_GT(windowed, 0);
}

}  // namespace
}  // namespace noisemon::model
