// In-memory sim campaigns as band datasets: the virtual engine (drivers/sim/sim_run) run for a list of conditions
// with effects injected, converted to 40 kHz recordings exactly as `noisemon diagnose` reads run directories
// (formats::to_recording, daemon::make_band_dataset), without touching the disk. What the withheld-effect
// proof tests and the diagnosis benchmark generate.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "cli/sim_run.hpp"
#include "drivers/formats/run_dir.hpp"
#include "model/engine/effects.hpp"
#include "model/fit/band_dataset.hpp"

namespace noisemon::cli {

struct SimCampaign {
  std::vector<cli::SimCondition> conditions;  // e.g. cli::thesis_conditions()
  int cycles = 12;
  model::engine::Effects effects;  // injected into the true engine of every condition
  model::BlockParams true_block = model::preset("linear");
  std::uint64_t seed = 1;  // per condition: cli::condition_seed(seed, name)
  std::uint64_t setup_seed = 1;
  // The engine and test cell of every run: encoder, pressure and microphone chains, gas ringing (realistic by
  // default; drivers::sim::with_ideal_cell(engine) for an ideal cell). Its operating point, true block, effects and
  // seed are set per condition from the fields above.
  drivers::sim::SimConfig engine = cli::SimRunSpec::default_engine();
  // Adds an engine-off run named "background" (cli::simulate_background_run on the time base of motored_idle),
  // which the diagnosis takes as the irreducible floor of the microphones.
  bool background_run = false;
  // Applied to each run after the sim, before conversion (a test's own effect outside the library).
  std::function<void(drivers::formats::RunDir&)> modify;
  model::fit::DatasetOptions dataset;
};

// Throws what simulate_run / to_recording / make_band_dataset throw.
model::fit::BandDataset simulate_band_dataset(const SimCampaign& campaign);

}  // namespace noisemon::cli
