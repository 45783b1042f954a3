// Fills SampleBlocks frame by frame for a driver thread and writes each full block to its ring. Shared by the
// sources that produce 40 kHz frames one at a time (sim generators, comedi stream assemblers).
#pragma once

#include <cmath>
#include <cstdint>

#include "drivers/source.hpp"

namespace noisemon::drivers {

// Writes each full block (and the partial one on flush) to the ring; a failed write is an overrun, counted by
// the ring. No allocation.
class BlockWriter {
 public:
  explicit BlockWriter(std::uint32_t channels) { block_.channels = channels; }
  // Frame `index` must follow the previous one (a jump flushes first); returns the slot for its channels.
  double* frame(std::int64_t index, BlockRing& ring) {
    if (block_.frames == SampleBlock::kMaxFrames ||
        (block_.frames > 0 && index != block_.first_index + static_cast<std::int64_t>(block_.frames)))
      flush(ring);
    if (block_.frames == 0) block_.first_index = index;
    return &block_.data[static_cast<std::size_t>(block_.frames++) * block_.channels];
  }
  // A frame off the 40 kHz grid (the crank-angle stream's edges, in order), at most max_frames a block: a new
  // block's first_index is the 40 kHz frame at or before its first edge, frame_index the edge's instant in frames.
  double* edge(double frame_index, std::uint32_t max_frames, BlockRing& ring) {
    if (block_.frames >= max_frames) flush(ring);
    if (block_.frames == 0) block_.first_index = static_cast<std::int64_t>(std::floor(frame_index));
    return &block_.data[static_cast<std::size_t>(block_.frames++) * block_.channels];
  }
  void flush(BlockRing& ring) {
    if (block_.frames == 0) return;
    if (ring.push(block_)) ++written_;
    block_.frames = 0;
  }
  std::uint32_t pending_frames() const { return block_.frames; }
  std::uint64_t blocks_written() const { return written_; }

 private:
  SampleBlock block_{};
  std::uint64_t written_ = 0;
};

}  // namespace noisemon::drivers
