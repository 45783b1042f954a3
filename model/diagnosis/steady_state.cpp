#include "model/diagnosis/steady_state.hpp"

#include <cmath>

namespace noisemon::model::diagnosis {

void SteadyStateGate::add(const OperatingSample& sample) {
  if (sample.time_s < latest_s_) samples_.clear();  // another run's clock
  latest_s_ = sample.time_s;
  flushed_ = false;
  samples_.push_back(sample);
  // Kept: what a cycle still waiting for its decision needs (a cycle's length of margin).
  const double keep_from = latest_s_ - options_.after_s - options_.before_s - 1.0;
  while (!samples_.empty() && samples_.front().time_s < keep_from) samples_.pop_front();
}

bool SteadyStateGate::steady(const OperatingSample& cycle) const {
  for (const OperatingSample& s : samples_) {
    if (s.time_s < cycle.time_s - options_.before_s || s.time_s > cycle.time_s + options_.after_s) continue;
    if (s.motored != cycle.motored || std::abs(s.speed_rpm - cycle.speed_rpm) > options_.speed_band_rpm ||
        std::abs(s.load_nm - cycle.load_nm) > options_.load_band_nm ||
        std::abs(s.soi_deg_btdc - cycle.soi_deg_btdc) > options_.soi_band_deg)
      return false;
  }
  return true;
}

}  // namespace noisemon::model::diagnosis
