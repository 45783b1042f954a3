// A recording's crank-angle stream held in memory: its encoder edges, frame-major, kEdgeValues values each (the
// edge's instant in 40 kHz frames, its crank angle, its pressure). How it is cut, written as raw blocks
// (drivers/source.hpp: crank angle and pressure per edge, the block's first_index at or before its first edge) and
// gathered back from them (an edge read back has its block's first_index as its instant).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "drivers/source.hpp"
#include "noisemon/raw_block_t.hpp"

namespace noisemon::cli::formats {

inline constexpr std::size_t kEdgeValues = 3;
inline constexpr std::size_t kEdgeInstant = 0, kEdgeCrank = 1, kEdgePressure = 2;

// The edges whose instants lie in [from, to) (40 kHz frames).
std::vector<double> edges_within(std::span<const double> edges, std::int64_t from, std::int64_t to);

// Fills `block` with the next edges from edges[next] on whose instants lie before `until`, at most
// max_edges_per_angle_block(step_deg), and advances next. False when there is none.
bool next_edge_block(std::span<const double> edges, std::size_t& next, double until, double step_deg,
                     std::int64_t epoch_utime, noisemon::raw_block_t& block);

// A crank-angle block read back: its first_index and its edges (frames x kAngleStreamChannels).
struct EdgeBlock {
  std::int64_t first;
  std::span<const double> values;
};
// Appends the edges of the blocks (sorted by first_index) that begin in [from, to) to out.
void gather_edges(std::span<const EdgeBlock> blocks, std::int64_t from, std::int64_t to, std::vector<double>& out);

}  // namespace noisemon::cli::formats
