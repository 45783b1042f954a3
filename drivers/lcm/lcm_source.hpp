// The `lcm` source: the 40 kHz streams as another process publishes them on LCM — lcm-logplayer replaying an
// lcm-logger recording, or a daemon elsewhere publishing its raw channels. Its one driver thread receives
// noisemon.raw_block_t and operating_point_t, decodes them with the one raw-stream decoder against the first
// session (raw_stream_decoder.hpp) and pushes them into the same rings as a hardware source. A block that does not
// fit the session (another epoch, channel count, damaged fields) is counted and dropped: it never reaches the
// processing.
#pragma once

#include <memory>
#include <string>

#include "drivers/source.hpp"
#include "drivers/worker_thread.hpp"

namespace noisemon::drivers::lcm {

struct LcmSourceConfig {
  std::string url;  // empty: LCM's default
  std::string raw_channel = "NOISEMON_RAW";
  std::string operating_point_channel = "NOISEMON_OP";
  std::string session_channel = "NOISEMON_SESSION";
  double session_timeout_s = 30.0;  // how long construction waits for the session message
  ThreadPolicy thread;              // scheduling of the receiving thread nm-lcm-in (the daemon's [threads.lcm_receive])
};

// Waits for a noisemon.session_t (time base, microphones) on the session channel; throws std::runtime_error
// naming the channel and URL when LCM cannot start or none arrives in time.
std::unique_ptr<Source> make_lcm_source(const LcmSourceConfig& config);

}  // namespace noisemon::drivers::lcm
