// A stream on a converter's own clock (a DAQ card's timer, an audio interface's crystal): its scans resampled from
// the converter's whole-Hz rate to the pipeline's 40 kHz frames (dsp::RationalResampler), placed on the source's
// frame grid from the host time of the first scan after each (re)start. Used by the comedi card's microphones and
// by the ALSA source; nothing in it knows the hardware.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "drivers/block_writer.hpp"
#include "drivers/source.hpp"
#include "dsp/resample.hpp"

namespace noisemon::drivers {

class TimedStreamAssembler {
 public:
  // card_rate_hz: whole Hz (the resampler's ratio must be rational); throws std::invalid_argument otherwise.
  // unknown_channels: each frame carries that many more channels after the resampled ones, NaN (the crank angle of a
  // pressure sampled on a timer with the engine at rest).
  TimedStreamAssembler(std::uint32_t channels, double card_rate_hz, std::int64_t epoch_utime,
                       std::uint32_t unknown_channels = 0);
  ~TimedStreamAssembler();

  // Starts over: card scan 0 is at origin_utime (rounded to the nearest 40 kHz frame, +-12.5 us).
  void restart(std::int64_t origin_utime);
  void add_scan(const double* values, BlockRing& ring);
  void deliver(BlockRing& ring, bool all);
  std::uint64_t frames() const { return frames_; }
  std::uint64_t blocks_written() const { return writer_.blocks_written(); }

  // Output frames dropped after each (re)start: the resampler's filter starts from silence.
  static constexpr std::int64_t kSettleFrames = dsp::kResamplerSettleFrames;

 private:
  void run_batch(BlockRing& ring);

  std::uint32_t channels_;
  std::uint32_t unknown_channels_;
  double card_rate_hz_;
  std::int64_t epoch_utime_;
  std::int64_t first_index_ = 0;  // 40 kHz index of card scan 0
  dsp::RationalResampler resampler_;
  std::vector<double> in_, out_;
  std::size_t batch_ = 0;
  BlockWriter writer_;
  std::uint64_t frames_ = 0;
};

}  // namespace noisemon::drivers
