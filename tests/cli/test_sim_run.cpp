// Simulated run directories (`noisemon sim`): the same spec gives the same bits, another seed other bits (the
// realistic cell's noise sources included: transducer noise, mechanical noise).
#include <gtest/gtest.h>

#include "cli/sim_run.hpp"
#include "model/engine/effects.hpp"

using namespace noisemon;

TEST(SimRun, TheSameSpecGivesTheSameBitsAndAnotherSeedOthers) {
  cli::SimRunSpec spec;
  spec.condition = cli::resolve_conditions({"full_mi21"}).front();
  spec.cycles = 2;
  spec.effects = model::engine::parse_effects({"transducer_noise", "mechanical_noise"});
  const drivers::formats::RunDir a = cli::simulate_run(spec), b = cli::simulate_run(spec);
  EXPECT_EQ(a.pressure_pa, b.pressure_pa);
  EXPECT_EQ(a.mic_pa, b.mic_pa);
  spec.seed = 2;
  const drivers::formats::RunDir c = cli::simulate_run(spec);
  EXPECT_NE(c.pressure_pa, a.pressure_pa);
  EXPECT_NE(c.mic_pa, a.mic_pa);
}
