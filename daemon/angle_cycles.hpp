// The crank-angle stream cut into engine cycles: each encoder edge's pressure goes onto a CrankGrid of the
// encoder's own step (the grid's origin on the edges, so each edge is a grid point and nothing is interpolated),
// a new cycle where the angle wraps from below +360 to -360, as the 40 kHz stream's cycles are cut.
//
// The cycle processor cuts the same cycles from the 40 kHz stream and asks here for the one that ends at its
// boundary. The edge that opens the next cycle lies within one edge spacing after the boundary's 40 kHz frame (the
// 40 kHz crank angle is interpolated between edges), and its block's first_index at most a block's span
// (kMaxAngleBlockDeg) before it. The processor takes a boundary only once a block that begins beyond its frame has
// arrived (covered_until()): the opening edge came before it. What is computed then depends on the samples alone,
// never on when they arrived: replay gives what the live run gave.
//
// Edges with an unknown angle (NaN), a step of more than kMaxStepsBridged encoder steps (lost blocks, missed edges)
// or a backward step are not bridged: the cycle's grid keeps NaN points and its figures are NaN.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "daemon/crank_grid.hpp"
#include "drivers/source.hpp"

namespace noisemon::daemon {

class AngleCycles {
 public:
  static constexpr double kMaxStepsBridged = 2.5;  // one missing edge is interpolated over, more are a gap

  // Completed cycles wait for the processor's boundary while they closed less than `horizon_frames` before the
  // newest edge: the span one stream may run ahead of another (the processor's fifo_seconds). A processing thread
  // that fell behind its drivers finds the edges far ahead of the frames it is cutting; a count of cycles kept
  // (it was 4, 160 ms at idle) voided every cycle's figures while the lag lasted, and nothing said why.
  AngleCycles(double step_deg, double horizon_frames);

  // A block of the crank-angle stream (drivers::kAngleStreamChannels channels), edges in time order.
  void add(const drivers::SampleBlock& block);
  // The latest block's first_index: every 40 kHz frame before it has an edge after it.
  [[nodiscard]] std::int64_t covered_until() const { return covered_until_; }
  [[nodiscard]] bool started() const { return covered_until_ != INT64_MIN; }  // a block has come
  [[nodiscard]] double step_deg() const { return step_deg_; }

  // The first completed cycle whose closing edge's block begins within `tolerance_frames` of the 40 kHz frame
  // `boundary`; nullptr when there is none (the stream had a gap there). Cycles closed before it are forgotten. The
  // grid may hold NaN points (complete() says); it stays valid until the next add() or take().
  CrankGrid* take(std::int64_t boundary, double tolerance_frames);

 private:
  struct Completed {
    CrankGrid grid;
    double closed_at = 0;  // the first_index of the closing edge's block (at most kMaxAngleBlockDeg before it)
  };
  void edge(double t, double crank_deg, double pressure_pa);
  void wrap(double t, double crank_deg, double pressure_pa);

  double step_deg_;
  double horizon_frames_;
  CrankGrid open_;
  bool open_valid_ = false;  // the open grid started at a wrap (a cycle before the first wrap is not whole)
  void recycle(Completed&& c) { spare_.push_back(std::move(c)); }

  std::vector<Completed> completed_;  // oldest first, closed within horizon_frames_ of the newest edge
  std::optional<Completed> taken_;    // what take() returned last
  std::vector<Completed> spare_;      // grids of forgotten cycles, reused: no allocation per cycle once warm
  double last_deg_ = 0;               // the last known angle (kept across unknown ones, to see the wrap)
  bool has_last_ = false;
  std::int64_t covered_until_ = INT64_MIN;
};

}  // namespace noisemon::daemon
