#include "drivers/sim/sim_effect_schedule.hpp"

#include <algorithm>

namespace noisemon::drivers::sim {

double effect_weight(const ScheduledEffect& effect, double since_start_s) {
  const double after = since_start_s - effect.onset_s;
  if (after < 0.0) return 0.0;
  if (effect.ramp_s <= 0.0) return 1.0;
  return std::min(1.0, after / effect.ramp_s);
}

model::engine::Effects cumulative_effects(const model::engine::Effects& fixed,
                                          const std::vector<ScheduledEffect>& schedule, std::size_t k) {
  model::engine::Effects effects = fixed;
  for (std::size_t i = 0; i < k && i < schedule.size(); ++i) effects.add(schedule[i].setting);
  return effects;
}

}  // namespace noisemon::drivers::sim
