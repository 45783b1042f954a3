#include "drivers/timed_stream.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace noisemon::drivers {
namespace {

constexpr std::size_t kCardBatch = 1024;  // card scans per resampler call

double whole_rate(double hz) {
  const double r = std::round(hz);
  if (!(r >= 1.0) || std::abs(hz - r) > 1e-6 * r)
    throw std::invalid_argument(
        "scan rate " + std::to_string(hz) +
        " Hz is not a whole number of Hz (choose a rate the converter's clock hits exactly, e.g. 48000 or 50000)");
  return r;
}
}  // namespace

TimedStreamAssembler::TimedStreamAssembler(std::uint32_t channels, double card_rate_hz, std::int64_t epoch_utime,
                                           std::uint32_t unknown_channels)
    : channels_(channels),
      unknown_channels_(unknown_channels),
      card_rate_hz_(whole_rate(card_rate_hz)),
      epoch_utime_(epoch_utime),
      resampler_(card_rate_hz_, kPipelineRateHz, channels),
      in_(kCardBatch * channels),
      out_((resampler_.max_output_frames(kCardBatch) + 1) * channels),
      writer_(channels + unknown_channels) {
  if (channels == 0 || channels + unknown_channels > SampleBlock::kMaxChannels)
    throw std::invalid_argument("timed stream needs 1.." + std::to_string(SampleBlock::kMaxChannels) + " channels");
}

TimedStreamAssembler::~TimedStreamAssembler() = default;

void TimedStreamAssembler::restart(std::int64_t origin_utime) {
  first_index_ = frame_of_utime(epoch_utime_, origin_utime);
  resampler_ =
      dsp::RationalResampler(card_rate_hz_, kPipelineRateHz, channels_, dsp::SamplePrecision::kSingle);  // ADC words
  batch_ = 0;
}

void TimedStreamAssembler::add_scan(const double* values, BlockRing& ring) {
  std::copy_n(values, channels_, &in_[batch_ * channels_]);
  if (++batch_ == kCardBatch) run_batch(ring);
}

void TimedStreamAssembler::run_batch(BlockRing& ring) {
  if (batch_ == 0) return;
  const std::size_t room = out_.size() / channels_;
  const std::size_t n = resampler_.process(in_.data(), batch_, out_.data(), room);
  batch_ = 0;
  std::int64_t local = resampler_.next_output_index() - static_cast<std::int64_t>(n);
  for (std::size_t f = 0; f < n; ++f, ++local) {
    if (local < kSettleFrames) continue;
    double* slot = writer_.frame(first_index_ + local, ring);
    std::copy_n(&out_[f * channels_], channels_, slot);
    std::fill_n(slot + channels_, unknown_channels_, std::numeric_limits<double>::quiet_NaN());
    ++frames_;
  }
}

void TimedStreamAssembler::deliver(BlockRing& ring, bool all) {
  run_batch(ring);
  if (all || writer_.pending_frames() >= SampleBlock::kMaxFrames / 2) writer_.flush(ring);
}

}  // namespace noisemon::drivers
