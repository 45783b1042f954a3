// Effects that switch on mid-run ([[sim.effects]] with onset_s and ramp_s): the virtual engine starts clean and
// turns bad, so the live gap watch (noisemon gapwatch) can be proven on a change whose instant and size are known.
//
// How a switched effect is rendered: the microphone generator runs one virtual engine per step of the schedule,
// engine k with the configured effects plus the first k scheduled ones, all from the same seeds, and mixes
//   out = E0 + sum_k w_k(t) (E_k - E_(k-1)),
// w_k the k-th effect's weight (0 before its onset, rising linearly to 1 over ramp_s, 1 after). The engines share
// every random stream, so E_k - E_(k-1) is exactly what the k-th effect adds to the microphones: a step is the effect
// switched on between two samples, a ramp grows its contribution linearly in amplitude (mic_gain: the factor
// 1 + w (g - 1); additive noise: its pressure w times its full size). transducer_noise acts on the measured pressure
// alone: w times its own counter-based noise (independent of the chain's floor) before the pressure chain's ADC.
#pragma once

#include <vector>

#include "model/engine/effects.hpp"

namespace noisemon::drivers::sim {

struct ScheduledEffect {
  model::engine::EffectSetting setting;  // the spelling of `noisemon sim --effect`
  double onset_s = 0.0;                  // source seconds after the first frame
  double ramp_s = 0.0;                   // 0: a step; otherwise a linear rise to full size over ramp_s
};

// The k-th effect's weight at `since_start_s` seconds after the first frame: 0 ... 1.
[[nodiscard]] double effect_weight(const ScheduledEffect& effect, double since_start_s);

// The effects of engine k (0 ... schedule.size()): the static ones plus the first k scheduled. Throws
// std::invalid_argument (Effects::add's message) for an effect given twice.
[[nodiscard]] model::engine::Effects cumulative_effects(const model::engine::Effects& fixed,
                                                        const std::vector<ScheduledEffect>& schedule, std::size_t k);

}  // namespace noisemon::drivers::sim
