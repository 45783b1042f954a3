// The log source: a raw LCM log (lcm-logger's recording of NOISEMON_SESSION, NOISEMON_RAW and NOISEMON_OP, or a
// `noisemon import`) as a Source, read with the tolerant log reader (lcm_log_reader.hpp) and the one raw-stream
// decoder (raw_stream_decoder.hpp): what `noisemon replay` runs the daemon's pipeline on.
//
// A log may hold several runs (sessions), and a pipeline has one time base: LogSessions hands out one Source per
// session, which ends (exhausted()) where its session does. Unlike a live source it never drops data: it waits
// while a ring is full, and an operating point that changes waits until the processing has taken every block
// before it (and the blocks after it wait for the operating point), so every cycle carries the operating point
// the log gives it, however the threads are scheduled.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "drivers/formats/lcm_log_reader.hpp"
#include "drivers/formats/raw_stream_decoder.hpp"
#include "drivers/source.hpp"
#include "drivers/worker_thread.hpp"

namespace noisemon::drivers::log {

// An event that is not used: it does not decode, or contradicts its session or itself (raw_stream_decoder.hpp).
struct LogDamage {
  std::int64_t eventnum = 0;
  std::string_view channel;
  std::string_view reason;
};

struct LogSourceConfig {
  std::string path;
  formats::StreamChannels channels;
  bool realtime = false;  // at the recorded pace (the events' timestamps); false: as fast as the pipeline takes it
  ThreadPolicy thread;    // scheduling of the reading thread nm-log-in
  // Called for every damaged event, on the thread that reads it.
  std::function<void(const LogDamage&)> on_damaged;
};

struct LogCounts {
  std::int64_t events = 0;          // well-framed events read
  std::int64_t sessions = 0;        // sessions started
  std::int64_t raw_blocks = 0;      // blocks delivered into the rings
  std::int64_t other_channels = 0;  // events of channels the decoder does not read
  std::int64_t damaged = 0;         // events that were not used (LogDamage)
};

class LogSessions {
 public:
  // Maps the file; throws std::runtime_error naming it when it cannot be opened.
  explicit LogSessions(LogSourceConfig config);
  ~LogSessions();
  LogSessions(const LogSessions&) = delete;
  LogSessions& operator=(const LogSessions&) = delete;

  // The source of the next session, read up to its start (the rest of the previous one is skipped); nullptr when
  // the log holds no further session. Call it only while no source of this log runs. A raw block before any
  // session message is an error naming the file and the event (std::runtime_error).
  std::unique_ptr<Source> next_session();
  // The run condition of the session last handed out (session_t::condition).
  const std::string& condition() const;
  // Waits until the source last handed out has delivered its whole session (true), or the timeout (false).
  bool wait_for_session_end(std::chrono::milliseconds timeout) const;

  // Safe from any thread: how far the log has been read, 0..1.
  double fraction_read() const;
  // Complete once no source of this log runs.
  LogCounts counts() const;
  // The file's framing: damaged stretches (they are no event) and a log cut short.
  const formats::LcmLogReader& reader() const;

  struct State;

 private:
  std::shared_ptr<State> state_;
};

}  // namespace noisemon::drivers::log
