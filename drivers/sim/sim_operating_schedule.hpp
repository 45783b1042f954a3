// The virtual engine's operating point over a run ([[sim.schedule]]): speed, load and injection timing change
// mid-run, so a long run visits several operating points as a test cell's does.
//
// A change takes effect at the first cycle boundary at or after its instant (an engine cycle has one operating
// point); with ramp_s > 0 it goes there cycle by cycle, linearly over ramp_s (a governor's ramp), motored or fired
// switching at the first changed cycle. The crank kinematics follow the cycles' speeds (model::CrankKinematics with
// one speed step per changed cycle), so the encoder, the pressure and the microphones of every driver thread see the
// same engine.
#pragma once

#include <cstdint>
#include <vector>

#include "model/engine/effects.hpp"
#include "model/engine/engine_cycle.hpp"
#include "model/engine_geometry.hpp"

namespace noisemon::drivers::sim {

struct OperatingStep {
  double at_s = 0.0;    // source seconds after the first frame
  double ramp_s = 0.0;  // 0: a step at the next cycle boundary; otherwise cycle by cycle over ramp_s
  model::engine::OperatingCondition condition;
};

// Throws std::invalid_argument naming the step and field: instants increasing, a ramp over before the next step,
// speed in (0, 10000] rpm, load >= 0, SOI in [0, 60] deg BTDC.
void validate_operating_schedule(const std::vector<OperatingStep>& schedule);

// Effects whose size follows the operating point (speed_dependence, mechanical_noise, the foreign SOI gain): a
// schedule cannot carry them (the virtual engine sizes them once, at the first point).
[[nodiscard]] inline bool sized_by_operating_point(const model::engine::Effects& e) {
  return e.speed_dependence_db_per_krpm != 0.0 || e.foreign_soi_gain_db_per_deg != 0.0 ||
         e.mechanical_noise_dba.has_value();
}

class OperatingProfile {
 public:
  // initial: the run's operating point from its start; t_first_s: the source instant of the first frame (the
  // schedule's zero); the engine's cycle 0 begins at source time 0.
  OperatingProfile(const model::engine::OperatingCondition& initial, const std::vector<OperatingStep>& schedule,
                   double speed_fluctuation, double t_first_s);

  [[nodiscard]] const model::CrankKinematics& kinematics() const { return kinematics_; }
  // The operating point of engine cycle k (model::CrankKinematics::cycle_index).
  [[nodiscard]] const model::engine::OperatingCondition& condition(std::int64_t cycle) const;
  [[nodiscard]] double min_speed_rpm() const { return min_rpm_; }
  [[nodiscard]] double max_speed_rpm() const { return max_rpm_; }

 private:
  struct Span {
    std::int64_t first_cycle;
    double t_s;  // its first cycle's start
    model::engine::OperatingCondition condition;
  };
  void add_step(const OperatingStep& step, double t_first_s);
  void append(std::int64_t cycle, const model::engine::OperatingCondition& condition);

  std::vector<Span> spans_;
  double min_rpm_, max_rpm_;
  model::CrankKinematics kinematics_;
};

}  // namespace noisemon::drivers::sim
