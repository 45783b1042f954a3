// Which cycles ran at a steady operating point: the gap watch compares a cycle with its operating point's reference
// only when the engine held that point around it. Through a change of speed, load or injection timing (a governor's
// ramp, a step of the dynamometer) the cycles in and near the change sit within an operating point's tolerances
// while the engine moves; their gap follows the move, not the model, and a watch that took them would fire on every
// change (a test bed's steady-state criterion, as a combustion analyser's averaging waits for one).
//
// A cycle is steady when every operating point reported from `before_s` before it to `after_s` after it lies
// within the band around its own (speed, load, SOI; motored or fired the same). The decision waits for `after_s`
// of later reports.
#pragma once

#include <deque>

namespace noisemon::model::diagnosis {

struct SteadyStateOptions {
  double before_s = 5.0;         // the engine held the point this long before the cycle ...
  double after_s = 2.0;          // ... and this long after it
  double speed_band_rpm = 30.0;  // half the watch's tolerances: a point's own spread, never its neighbour's
  double load_band_nm = 1.0;
  double soi_band_deg = 0.5;
};

struct OperatingSample {
  double time_s = 0.0;
  double speed_rpm = 0.0, load_nm = 0.0, soi_deg_btdc = 0.0;
  bool motored = false;
};

class SteadyStateGate {
 public:
  explicit SteadyStateGate(const SteadyStateOptions& options) : options_(options) {}

  // The operating point of the next cycle report, in order (a clock that runs back starts afresh).
  void add(const OperatingSample& sample);
  // Whether a cycle at time_s can be judged: after_s of later reports have come (or flush() said so).
  [[nodiscard]] bool decided(double time_s) const { return time_s + options_.after_s <= latest_s_ || flushed_; }
  // Whether the cycle of this sample ran at a steady point, over the reports at hand.
  [[nodiscard]] bool steady(const OperatingSample& sample) const;
  // The stream has ended: the cycles still waiting are judged on what came.
  void flush() { flushed_ = true; }

 private:
  SteadyStateOptions options_;
  std::deque<OperatingSample> samples_;
  double latest_s_ = -1e300;
  bool flushed_ = false;
};

}  // namespace noisemon::model::diagnosis
