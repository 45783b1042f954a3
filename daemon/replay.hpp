// `noisemon replay`: runs a raw LCM log (as lcm-logger records noisemond's NOISEMON_RAW, NOISEMON_OP and
// NOISEMON_SESSION channels) through the daemon's own pipeline (pipeline.hpp) with the log source
// (drivers/log/log_source.hpp), one pipeline per session, as fast as the machine allows or at the recorded speed,
// and publishes the cycle reports to an LCM log and/or CSV (log_publisher.hpp, csv_publisher.hpp).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/publisher.hpp"
#include "noisemon/cycle_report_t.hpp"

namespace noisemon::daemon {

struct ReplayOptions {
  std::string log_path;
  std::string out_log;   // cycle reports as an LCM log (channel config.lcm.report_channel); empty: none
  std::string csv_path;  // one row per cycle; empty: none
  std::vector<std::shared_ptr<Publisher>> publishers;  // further outputs (the tool's HDF5 file)
  bool realtime = false;                               // pace events at their recorded times
  bool progress = true;                                // progress bar on stderr when it is a terminal
  Config config;                                       // model parameters and channel names
  // Called with every cycle report and its run's condition name (may be empty).
  std::function<void(const noisemon::cycle_report_t&, const std::string&)> on_report;
};

struct ReplaySummary {
  std::int64_t events = 0;
  std::int64_t sessions = 0;  // runs: a new epoch starts a fresh pipeline (cycle numbers restart at 0)
  std::int64_t raw_blocks = 0;
  std::int64_t reports = 0;
  std::int64_t cycles_dropped = 0;
  std::int64_t skipped_unknown = 0;  // events on channels replay does not read
  std::int64_t skipped_damaged = 0;  // events on known channels that did not decode or fit, damaged stretches
};

// Throws std::runtime_error naming the file (and event) when the log cannot be replayed.
ReplaySummary run_replay(const ReplayOptions& options);

}  // namespace noisemon::daemon
