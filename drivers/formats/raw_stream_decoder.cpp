#include "drivers/formats/raw_stream_decoder.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include "drivers/formats/stream_messages.hpp"

namespace noisemon::drivers::formats {

BlockRing* ring_of(const Streams& streams, std::int8_t stream) {
  if (stream == noisemon::raw_block_t::STREAM_PRESSURE) return streams.pressure;
  if (stream == noisemon::raw_block_t::STREAM_MICS) return streams.mics;
  if (stream == noisemon::raw_block_t::STREAM_PRESSURE_ANGLE) return streams.pressure_angle;
  return nullptr;
}

RawStreamDecoder::RawStreamDecoder(RawStreamDecoderOptions options) : options_(std::move(options)) {}

const RawEvent& RawStreamDecoder::decode(std::string_view channel, const void* data, std::size_t size) {
  event_.reason.clear();
  event_.session_started = false;
  if (channel == options_.channels.raw) {
    event_.channel = RawChannel::kRaw;
    return raw_block(data, size);
  }
  if (channel == options_.channels.operating_point) {
    event_.channel = RawChannel::kOperatingPoint;
    return operating_point(data, size);
  }
  if (channel == options_.channels.session) {
    event_.channel = RawChannel::kSession;
    return session(data, size);
  }
  event_.channel = RawChannel::kOther;
  event_.kind = RawEventKind::kOtherChannel;
  return event_;
}

const RawEvent& RawStreamDecoder::session(const void* data, std::size_t size) {
  noisemon::session_t m;
  if (!decode_message(data, size, m)) return damaged("does not decode as noisemon.session_t");
  StreamInfo next;
  try {
    next = from_message(m);
  } catch (const std::invalid_argument& e) {
    return damaged(e.what());
  }
  if (m.nmics > 0 && static_cast<std::size_t>(m.nmics) != next.mic_positions_m.size())
    return damaged("session microphone positions do not match nmics");
  event_.kind = RawEventKind::kSession;
  const bool same = has_session_ && info_.epoch_utime == next.epoch_utime && info_.mic_count == next.mic_count &&
                    condition_ == m.condition;
  if (same || (has_session_ && options_.sessions == SessionChanges::kKeepFirst)) return event_;
  has_session_ = true;
  info_ = std::move(next);
  condition_ = m.condition;
  source_ = m.source;
  event_.session_started = true;
  return event_;
}

const RawEvent& RawStreamDecoder::raw_block(const void* data, std::size_t size) {
  if (!decode_message(data, size, raw_)) return damaged("does not decode as noisemon.raw_block_t");
  if (!has_session_) {
    event_.kind = RawEventKind::kBeforeSession;
    return event_;
  }
  event_.reason = options_.blocks == BlockCheck::kFinite ? raw_block_problem_for_recording(raw_, info_)
                                                         : raw_block_problem(raw_, info_);
  if (!event_.reason.empty()) {
    event_.kind = raw_.epoch_utime != info_.epoch_utime ? RawEventKind::kOtherSessionBlock : RawEventKind::kBadBlock;
    return event_;
  }
  // raw_block_problem has checked the shape: the samples fit a SampleBlock.
  SampleBlock& b = event_.block;
  b.first_index = raw_.first_index;
  b.frames = static_cast<std::uint32_t>(raw_.frames);
  b.channels = static_cast<std::uint32_t>(raw_.channels);
  std::copy(raw_.data.begin(), raw_.data.end(), b.data);
  event_.stream = raw_.stream;
  event_.kind = RawEventKind::kBlock;
  return event_;
}

const RawEvent& RawStreamDecoder::operating_point(const void* data, std::size_t size) {
  noisemon::operating_point_t m;
  if (!decode_message(data, size, m)) return damaged("does not decode as noisemon.operating_point_t");
  event_.kind = has_session_ ? RawEventKind::kOperatingPoint : RawEventKind::kBeforeSession;
  event_.operating_point = from_message(m);
  return event_;
}

const RawEvent& RawStreamDecoder::damaged(std::string reason) {
  event_.kind = RawEventKind::kDamaged;
  event_.reason = std::move(reason);
  return event_;
}

}  // namespace noisemon::drivers::formats
