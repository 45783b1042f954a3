#include "cli/formats/angle_edges.hpp"

#include <algorithm>
#include <cmath>

#include "drivers/formats/stream_messages.hpp"

namespace noisemon::cli::formats {
namespace {
double instant(std::span<const double> edges, std::size_t i) { return edges[i * kEdgeValues + kEdgeInstant]; }
}  // namespace

std::vector<double> edges_within(std::span<const double> edges, std::int64_t from, std::int64_t to) {
  std::vector<double> out;
  for (std::size_t i = 0; i < edges.size() / kEdgeValues; ++i) {
    const double t = instant(edges, i);
    if (t >= static_cast<double>(from) && t < static_cast<double>(to))
      out.insert(out.end(), edges.begin() + static_cast<std::ptrdiff_t>(i * kEdgeValues),
                 edges.begin() + static_cast<std::ptrdiff_t>((i + 1) * kEdgeValues));
  }
  return out;
}

bool next_edge_block(std::span<const double> edges, std::size_t& next, double until, double step_deg,
                     std::int64_t epoch_utime, noisemon::raw_block_t& block) {
  const std::size_t n = edges.size() / kEdgeValues, most = drivers::max_edges_per_angle_block(step_deg);
  std::size_t end = next;
  while (end < n && end - next < most && instant(edges, end) < until) ++end;
  if (end == next) return false;
  const auto first = static_cast<std::int64_t>(std::floor(instant(edges, next)));
  drivers::formats::set_raw_block(block, first, end - next, drivers::kAngleStreamChannels,
                                  noisemon::raw_block_t::STREAM_PRESSURE_ANGLE, epoch_utime);
  for (std::size_t i = next; i < end; ++i) {
    double* e = &block.data[(i - next) * drivers::kAngleStreamChannels];
    e[drivers::kAngleCrankChannel] = edges[i * kEdgeValues + kEdgeCrank];
    e[drivers::kAnglePressureChannel] = edges[i * kEdgeValues + kEdgePressure];
  }
  next = end;
  return true;
}

void gather_edges(std::span<const EdgeBlock> blocks, std::int64_t from, std::int64_t to, std::vector<double>& out) {
  for (const EdgeBlock& b : blocks) {
    if (b.first >= to) break;
    if (b.first < from) continue;
    for (std::size_t i = 0; i < b.values.size() / drivers::kAngleStreamChannels; ++i)
      out.insert(out.end(), {static_cast<double>(b.first),
                             b.values[i * drivers::kAngleStreamChannels + drivers::kAngleCrankChannel],
                             b.values[i * drivers::kAngleStreamChannels + drivers::kAnglePressureChannel]});
  }
}

}  // namespace noisemon::cli::formats
