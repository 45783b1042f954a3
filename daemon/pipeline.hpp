// The one pipeline of the daemon and of `noisemon replay`: a source's driver threads -> lock-free rings -> the
// processing thread (CycleProcessor) -> a lock-free report queue -> the publishing thread, which hands cycle
// reports, raw blocks, operating points, the session and a 1 Hz status message to a Publisher (the LCM bus, a log
// file, a CSV file or memory: publisher.hpp).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "daemon/config.hpp"
#include "daemon/cycle_report.hpp"
#include "daemon/publisher.hpp"
#include "drivers/source.hpp"

namespace noisemon::daemon {

struct PipelineOptions {
  // Called on the publishing thread after each cycle report is published (e.g. the live display).
  std::function<void(const CycleReport&)> on_report;
  // For a source that never drops data (a log file): the processing thread waits for room in the report queue
  // instead of dropping the cycle, so nothing is lost however slow the publisher; and it looks for blocks every
  // 0.1 ms when idle (not 1 ms), so a pipeline that runs as fast as the machine allows does not wait on it.
  bool lossless = false;
  // How far one stream may run ahead of another before its frames are discarded, s; 0: the daemon's
  // max(1 s, 2 x ring_seconds).
  double fifo_seconds = 0;
  // No info messages when it starts and stops (replay runs one pipeline per run of a log, on the user's terminal).
  bool quiet = false;
};

class Pipeline {
 public:
  Pipeline(const Config& config, std::unique_ptr<drivers::Source> source, std::shared_ptr<Publisher> publisher,
           PipelineOptions options = {});
  ~Pipeline();

  // Starts the processing, publishing and driver threads, once per pipeline (a new configuration is a new pipeline).
  // Throws with a clear message when the source fails.
  void start();
  // Stops the drivers, processes and publishes every complete cycle already acquired, joins all threads.
  void stop();

  bool ready() const;  // every driver thread delivers data
  // The configured number of cycles is published, the source has delivered all it has (a log), or a thread failed.
  bool finished() const;
  std::string failure() const;  // why a thread failed; empty otherwise
  std::int64_t cycles_published() const { return published_.load(); }
  std::int64_t cycles_dropped() const;
  // Every thread runs, and the processing and publishing loops went round within max_beat_age_s (the service
  // watchdog is fed only while this holds).
  bool healthy(double max_beat_age_s) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<std::int64_t> published_{0};
};

}  // namespace noisemon::daemon
