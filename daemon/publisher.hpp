// Where the pipeline's messages go, after Drake's lcm/ (DrakeLcmInterface with its live, log and in-memory
// implementations): one interface, so the daemon, `noisemon replay` and the tests run the same pipeline into the
// LCM bus (lcm_publisher.hpp), an LCM log file (log_publisher.hpp), a CSV file of the cycle reports
// (csv_publisher.hpp) or memory (memory_publisher.hpp).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "noisemon/cycle_report_t.hpp"
#include "noisemon/cycle_stats_t.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/raw_block_t.hpp"
#include "noisemon/session_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::daemon {

// Called from one thread at a time (the pipeline's publishing thread). `utime` is the instant the message stands
// for (the end of a cycle's window, a block's first frame, the wall clock for the status): what a log file stamps
// the event with. Every publisher takes the cycle reports; the other messages are ignored unless it keeps them.
// A failure throws (it fails the publishing thread, and the pipeline says why).
class Publisher {
 public:
  virtual ~Publisher() = default;
  virtual void publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t utime) = 0;
  virtual void publish(const std::string&, const noisemon::status_t&, std::int64_t) {}
  virtual void publish(const std::string&, const noisemon::session_t&, std::int64_t) {}
  virtual void publish(const std::string&, const noisemon::raw_block_t&, std::int64_t) {}
  virtual void publish(const std::string&, const noisemon::operating_point_t&, std::int64_t) {}
  virtual void publish(const std::string&, const noisemon::cycle_stats_t&, std::int64_t) {}
  // The run the following cycle reports belong to (session_t::condition; "" when unknown): replay starts one per
  // session of a log, before its pipeline publishes. Files that keep runs apart (CSV, HDF5) mark them.
  virtual void begin_run(const std::string& /*condition*/) {}
  // Makes what was published so far durable (files written out); the pipeline calls it when it stops.
  virtual void flush() {}
};

// Every message to each of several publishers, in the order they were added.
class FanoutPublisher final : public Publisher {
 public:
  void add(std::shared_ptr<Publisher> publisher) { publishers_.push_back(std::move(publisher)); }
  bool empty() const { return publishers_.empty(); }

  void publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish(channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::status_t& m, std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish(channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::session_t& m, std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish(channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::raw_block_t& m, std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish(channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::operating_point_t& m, std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish(channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::cycle_stats_t& m, std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish(channel, m, utime);
  }
  void begin_run(const std::string& condition) override {
    for (const auto& p : publishers_) p->begin_run(condition);
  }
  void flush() override {
    for (const auto& p : publishers_) p->flush();
  }

 private:
  std::vector<std::shared_ptr<Publisher>> publishers_;
};

}  // namespace noisemon::daemon
