#include "drivers/sim/sim_operating_schedule.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace noisemon::drivers::sim {

namespace {

constexpr double kCycleDeg = 720.0;  // one four-stroke cycle

model::engine::OperatingCondition between(const model::engine::OperatingCondition& a,
                                          const model::engine::OperatingCondition& b, double w) {
  return {.speed_rpm = a.speed_rpm + w * (b.speed_rpm - a.speed_rpm),
          .load_nm = a.load_nm + w * (b.load_nm - a.load_nm),
          .soi_deg_btdc = a.soi_deg_btdc + w * (b.soi_deg_btdc - a.soi_deg_btdc),
          .motored = b.motored};
}

}  // namespace

void validate_operating_schedule(const std::vector<OperatingStep>& schedule) {
  for (std::size_t i = 0; i < schedule.size(); ++i) {
    const OperatingStep& s = schedule[i];
    const auto fail = [i](const std::string& what) {
      throw std::invalid_argument("sim.schedule[" + std::to_string(i) + "]: " + what);
    };
    if (!(s.at_s >= 0.0)) fail("at_s must be >= 0");
    if (!(s.ramp_s >= 0.0)) fail("ramp_s must be >= 0");
    if (i > 0 && !(s.at_s > schedule[i - 1].at_s + schedule[i - 1].ramp_s))
      fail("at_s must come after the previous step's at_s + ramp_s");
    if (!(s.condition.speed_rpm > 0.0 && s.condition.speed_rpm <= 10000.0)) fail("speed_rpm must be in (0, 10000]");
    if (!(s.condition.load_nm >= 0.0)) fail("load_nm must be >= 0");
    if (!(s.condition.soi_deg_btdc >= 0.0 && s.condition.soi_deg_btdc <= 60.0)) fail("soi_deg_btdc must be in [0, 60]");
  }
}

OperatingProfile::OperatingProfile(const model::engine::OperatingCondition& initial,
                                   const std::vector<OperatingStep>& schedule, double speed_fluctuation,
                                   double t_first_s)
    : spans_{{0, 0.0, initial}},
      min_rpm_(initial.speed_rpm),
      max_rpm_(initial.speed_rpm),
      kinematics_(initial.speed_rpm, speed_fluctuation) {
  validate_operating_schedule(schedule);
  for (const OperatingStep& step : schedule) add_step(step, t_first_s);
  std::vector<model::CrankKinematics::SpeedStep> steps;
  for (const Span& s : spans_)
    steps.push_back({s.t_s, kCycleDeg * static_cast<double>(s.first_cycle) - 360.0, s.condition.speed_rpm});
  kinematics_ = model::CrankKinematics(std::move(steps), speed_fluctuation);
}

// The step's change from the first cycle boundary at or after its instant: at once, or one cycle at a time over
// its ramp (at least one cycle; each changed cycle a span).
void OperatingProfile::add_step(const OperatingStep& step, double t_first_s) {
  const Span last = spans_.back();
  const double period_s = 120.0 / last.condition.speed_rpm;
  const double cycles_to_step = std::ceil((t_first_s + step.at_s - last.t_s) / period_s - 1e-9);
  const std::int64_t first = last.first_cycle + std::max<std::int64_t>(1, static_cast<std::int64_t>(cycles_to_step));
  const double mean_period_s = 240.0 / (last.condition.speed_rpm + step.condition.speed_rpm);
  const auto ramp_cycles = std::max<std::int64_t>(1, std::llround(step.ramp_s / mean_period_s));
  for (std::int64_t j = 1; j <= ramp_cycles; ++j)
    append(first + j - 1,
           between(last.condition, step.condition, static_cast<double>(j) / static_cast<double>(ramp_cycles)));
}

void OperatingProfile::append(std::int64_t cycle, const model::engine::OperatingCondition& condition) {
  const Span& last = spans_.back();
  const double t_s = last.t_s + static_cast<double>(cycle - last.first_cycle) * 120.0 / last.condition.speed_rpm;
  spans_.push_back({cycle, t_s, condition});
  min_rpm_ = std::min(min_rpm_, condition.speed_rpm);
  max_rpm_ = std::max(max_rpm_, condition.speed_rpm);
}

const model::engine::OperatingCondition& OperatingProfile::condition(std::int64_t cycle) const {
  auto after = std::upper_bound(spans_.begin() + 1, spans_.end(), cycle,
                                [](std::int64_t k, const Span& s) { return k < s.first_cycle; });
  return (after - 1)->condition;
}

}  // namespace noisemon::drivers::sim
