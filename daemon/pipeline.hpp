// The running daemon: a source's driver threads -> lock-free rings -> the processing thread (CycleProcessor)
// -> a lock-free report queue -> the LCM thread, which publishes cycle reports, raw blocks, operating points
// and a 1 Hz status message.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "daemon/config.hpp"
#include "daemon/cycle_report.hpp"
#include "drivers/source.hpp"

namespace noisemon::daemon {

class Pipeline {
 public:
  // on_report: called on the LCM thread after each cycle report is published (e.g. the live display).
  using ReportHook = std::function<void(const CycleReport&)>;

  Pipeline(const Config& config, std::unique_ptr<drivers::Source> source, ReportHook on_report = {});
  ~Pipeline();

  // Starts the driver, processing and LCM threads. Throws with a clear message when LCM or the source fails.
  void start();
  // Stops the drivers, processes and publishes every complete cycle already acquired, joins all threads.
  void stop();

  bool ready() const;     // every driver thread delivers data
  bool finished() const;  // the configured number of cycles is published, or a thread failed
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
