// The one decoder of the raw stream (NOISEMON_SESSION, NOISEMON_RAW, NOISEMON_OP): every reader of it — the lcm
// source, the log source (`noisemon replay`) and the recordings (`noisemon export`, `diagnose`) — turns each
// (channel, payload) into one event here, by one set of rules:
//
// - a session message starts a session when it is the first, or when its epoch, microphone count or condition
//   differ from the current one (another run); repeats of the current one (the daemon sends it every second) do
//   not. SessionChanges::kKeepFirst keeps the first session for good (a live pipeline cannot change its time base).
// - a raw block is checked against the current session (raw_block_problem: rate, shape, epoch, utime, stream,
//   channel count, samples); BlockCheck::kFinite also refuses NaN samples (recordings for fits).
// - a payload that does not decode as its channel's type is damaged, with the reason.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "drivers/source.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/raw_block_t.hpp"
#include "noisemon/session_t.hpp"

namespace noisemon::drivers::formats {

struct StreamChannels {
  std::string raw = "NOISEMON_RAW";
  std::string operating_point = "NOISEMON_OP";
  std::string session = "NOISEMON_SESSION";
};

enum class SessionChanges : std::uint8_t {
  kFollow,     // another run's session message starts a new session (logs of several runs)
  kKeepFirst,  // the first session stays; other runs' messages are repeats and their blocks kOtherSessionBlock
};

enum class BlockCheck : std::uint8_t {
  kAsDelivered,  // raw_block_problem: NaN samples pass (the processing flags them)
  kFinite,       // raw_block_problem_for_recording: NaN samples are damage too
};

struct RawStreamDecoderOptions {
  StreamChannels channels;
  SessionChanges sessions = SessionChanges::kFollow;
  BlockCheck blocks = BlockCheck::kAsDelivered;
};

enum class RawChannel : std::uint8_t { kSession, kRaw, kOperatingPoint, kOther };

enum class RawEventKind : std::uint8_t {
  kSession,            // a session message: RawEvent::session_started says whether it starts a session
  kBlock,              // a raw block that fits the current session: RawEvent::stream, RawEvent::block
  kOperatingPoint,     // RawEvent::operating_point
  kDamaged,            // does not decode as its channel's type, or a session that is none: RawEvent::reason
  kBadBlock,           // a raw block that decodes but contradicts its session or itself: RawEvent::reason
  kOtherSessionBlock,  // a raw block of another epoch than the current session's: RawEvent::reason
  kBeforeSession,      // a raw block or operating point before any session: nothing to attach it to
  kOtherChannel,       // a channel the decoder does not read
};

struct RawEvent {
  RawEventKind kind = RawEventKind::kOtherChannel;
  RawChannel channel = RawChannel::kOther;
  bool session_started = false;  // kSession: the first session, or (kFollow) another run's
  std::int8_t stream = 0;        // kBlock: noisemon::raw_block_t::STREAM_PRESSURE, STREAM_MICS or STREAM_PRESSURE_ANGLE
  SampleBlock block;             // kBlock
  OperatingPoint operating_point;
  std::string reason;  // kDamaged, kBadBlock, kOtherSessionBlock
};

// The ring of `streams` a raw block of `stream` (noisemon::raw_block_t::STREAM_*) goes to; nullptr when it has none
// (a reader that does not take the crank-angle stream).
BlockRing* ring_of(const Streams& streams, std::int8_t stream);

// Not thread-safe: one reader thread at a time. Decoding a raw block allocates only while its sample buffer
// grows (the first blocks).
class RawStreamDecoder {
 public:
  explicit RawStreamDecoder(RawStreamDecoderOptions options = {});

  // The event of one message; valid until the next call.
  const RawEvent& decode(std::string_view channel, const void* data, std::size_t size);

  bool has_session() const { return has_session_; }
  // The current session (valid when has_session()): time base and microphones, its run's condition and source.
  const StreamInfo& info() const { return info_; }
  const std::string& condition() const { return condition_; }
  const std::string& source() const { return source_; }
  const StreamChannels& channels() const { return options_.channels; }

 private:
  const RawEvent& session(const void* data, std::size_t size);
  const RawEvent& raw_block(const void* data, std::size_t size);
  const RawEvent& operating_point(const void* data, std::size_t size);
  const RawEvent& damaged(std::string reason);

  RawStreamDecoderOptions options_;
  bool has_session_ = false;
  StreamInfo info_;
  std::string condition_, source_;
  noisemon::raw_block_t raw_;  // reused: decoding into a fresh message allocated its samples every time
  RawEvent event_;
};

}  // namespace noisemon::drivers::formats
