// One engine cycle's cylinder pressure on a uniform crank-angle grid, what the combustion metrics read: points at
// origin + k * step, k = 0 ... 720 / step (both gas-exchange TDCs, -360 and +360 re firing TDC, when the origin is
// -360). It is filled from samples in crank-angle order, linearly between consecutive ones; a point no pair of
// samples brackets stays NaN, and so does the cycle's metrics.
//
// Two feeds use it: the 40 kHz frames (a 0.25 deg grid, for sources whose pressure is not sampled on encoder edges)
// and the crank-angle stream's edges (the encoder's own step, so that each edge is a grid point: nothing is
// interpolated then, see angle_cycles.hpp).
#pragma once

#include <cstddef>
#include <vector>

#include "model/combustion_metrics.hpp"
#include "model/engine_geometry.hpp"

namespace noisemon::daemon {

class CrankGrid {
 public:
  explicit CrankGrid(double step_deg);

  // Every point NaN, the grid starting at origin_deg; the next sample starts a new line.
  void clear(double origin_deg);
  // A sample at crank_deg of this cycle (may run past +360 for the sample that closes it): the points between the
  // previous sample and this one are interpolated.
  void add(double crank_deg, double pressure_pa);
  // The next sample starts a new line (nothing is interpolated across: an unknown angle, lost samples).
  void break_line() { has_last_ = false; }
  // The sample that starts the next cycle, at crank_deg of the next cycle (just after -360): it closes this grid
  // (at crank_deg + 720); reopen() then starts the next grid from the last sample before it.
  void close(double crank_deg, double pressure_pa);
  void reopen(double origin_deg);

  [[nodiscard]] bool complete() const;
  [[nodiscard]] double step_deg() const { return step_deg_; }
  [[nodiscard]] double origin_deg() const { return origin_deg_; }
  [[nodiscard]] const std::vector<double>& values() const { return values_; }

  // The metrics of a complete grid whose firing TDC lies at the encoder's tdc_deg (MetricsOptions::tdc_deg): the
  // grid is turned by whole steps (its ends are gas-exchange TDC, where the cycle meets itself: the turned grid's
  // last point is its first again), the rest goes into its first angle, so that the figures see the piston's
  // angles. Leaves the values turned.
  model::CombustionMetrics metrics(const model::EngineGeometry& engine, double speed_rpm,
                                   const model::MetricsOptions& options, model::MetricsWorkspace& scratch);

 private:
  double step_deg_;
  double origin_deg_ = -360.0;
  std::vector<double> values_;
  double last_deg_ = 0.0, last_pa_ = 0.0;
  bool has_last_ = false;
  double carry_deg_ = 0.0, carry_pa_ = 0.0;  // the sample before the one that closed the grid
  bool has_carry_ = false;
};

}  // namespace noisemon::daemon
