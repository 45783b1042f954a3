// Whole runs of the virtual engine in memory, as run directories (drivers/formats/run_dir.hpp): what `noisemon sim`
// writes and what the diagnosis benchmark and tests generate.
//
//  simulate_run(spec)            the engine model's cylinder pressure on encoder samples through the pressure
//                                chain (floor, flicker, transducer_noise, ADC; the configured floor is recorded in
//                                pressure_noise_floor_bar) and the microphones at the card rate, from the virtual
//                                engine with the effects and the microphone chain.
//  simulate_background_run(spec) the engine off: the microphones hear only the test cell (its floor, the
//                                background_noise effect, their self-noise); the pressure channel reads ambient
//                                pressure through the chain. Named "background" (the diagnosis's floor run).
//  simulate_acoustics(run, spec) the microphones for a GIVEN pressure (e.g. real Yanmar cycles imported from a
//                                cycle table): the virtual engine driven by that pressure (`noisemon import
//                                --mics sim`, `noisemon sim --pressure`).
//
// Time base: t = 0 is the first encoder sample of simulate_run (crank -360 deg, the start of cycle 0) and the
// first frame of mics.wav. Both functions run the virtual engine from a pre-roll before t = 0 so the model and
// filters have settled when the recording starts. Deterministic in (spec.seed, spec.setup_seed).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "drivers/formats/run_dir.hpp"
#include "drivers/sim/sim_source.hpp"
#include "model/block_params.hpp"
#include "model/engine/effects.hpp"

namespace noisemon::cli {

// A named operating condition.
struct SimCondition {
  std::string name;
  double speed_rpm = 3050.0;
  double load_nm = 0.0;
  double soi_deg_btdc = 18.0;
  bool motored = false;
};

// The thesis's conditions (ch. 4.2): idle 3050 rpm / 0 N m and full load 3450 rpm / 20 N m (the sim's full
// fuelling), single injection at 12, 15, 18, 21, 24 deg BTDC: idle_mi12 ... idle_mi24, full_mi12 ... full_mi24;
// plus motored_idle and motored_full (no fuel, same speeds, 0 N m, injector commanded at 18 deg BTDC). 12 in all.
std::vector<SimCondition> thesis_conditions();
// Names (or "all") to conditions, in the order given without repeats. Throws std::invalid_argument naming the
// unknown name and listing the valid ones.
std::vector<SimCondition> resolve_conditions(const std::vector<std::string>& names);

struct SimRunSpec {
  SimCondition condition;
  int cycles = 40;  // whole engine cycles recorded (simulate_run)
  model::engine::Effects effects;
  model::BlockParams true_block = model::preset("linear");
  std::uint64_t seed = 1;        // this run's realisation: cycle-to-cycle variation, noise, impacts
  std::uint64_t setup_seed = 1;  // the installation: per-microphone spread (same for every run of a campaign)
  // Everything else (encoder resolution, speed ripple, cycle variation, microphone layout and rate, spread,
  // floor, speed of sound, the pressure and microphone chains, the gas ringing: realistic by default,
  // with_ideal_cell() for none). Its operating point, true block, effects and seed are replaced by the fields above.
  drivers::sim::SimConfig engine = default_engine();

  // The sim source's defaults with a 0.2 deg encoder (as the real Yanmar records; 91.5 kHz at 3050 rpm).
  static drivers::sim::SimConfig default_engine();
};

// A different but reproducible seed for each condition of a campaign seeded with `seed`.
std::uint64_t condition_seed(std::uint64_t seed, std::string_view condition_name);

// What the ADCs clipped while a run was made (never silent: `noisemon sim` reports it).
struct SimRunStats {
  std::uint64_t pressure_clipped = 0;  // encoder samples
  std::uint64_t mic_clipped = 0;       // card samples, every channel
};

drivers::formats::RunDir simulate_run(const SimRunSpec& spec, SimRunStats* stats = nullptr);

// The name of the engine-off run (a name the diagnosis recognises as a background measurement).
inline constexpr std::string_view kBackgroundRunName = "background";
// spec.cycles cycles of the engine off. The recording needs a clock: its time base is the encoder of a motored run
// at spec.condition's speed (speed_rpm, SOI as given, motored: true); the name is kBackgroundRunName; its
// pressure is the intake (ambient) pressure through the pressure chain; the microphones hear no engine (no
// combustion noise, no mechanical impacts), only the floor, background_noise and their self-noise (mic_gain
// still scales its channel).
drivers::formats::RunDir simulate_background_run(const SimRunSpec& spec, SimRunStats* stats = nullptr);

// Microphones for the pressure of `pressure_run` (its time_s, crank_deg and pressure_pa are the TRUE pressure for
// the virtual engine; the result's pressure is the given one plus spec.effects' transducer_noise: a recorded
// pressure has been through its own chain already, so the configured pressure chain is not applied again; the
// engine hears that pressure, noise and all, so the result states a floor of 0). The run needs at least one whole cycle
// (720 deg); its condition is kept (a speed of 0 is measured from the crank angle); spec.condition and
// spec.cycles are ignored. Microphone positions: the run's own when it has them, else spec.engine's (thesis).
// Existing microphone data is replaced. Throws std::invalid_argument naming what is wrong.
drivers::formats::RunDir simulate_acoustics(const drivers::formats::RunDir& pressure_run, const SimRunSpec& spec);

// The same for a recording on the 40 kHz grid (what `noisemon import --mics sim` holds): fills rec.mics_pa
// (40 kHz, frames() unchanged) and the microphone layout of rec.info; the pressure is left as it is (true).
// spec.condition is ignored: the condition comes from the recording's first operating point.
namespace formats {
struct Recording;
}
void synthesize_recording_mics(formats::Recording& rec, const SimRunSpec& spec);

}  // namespace noisemon::cli
