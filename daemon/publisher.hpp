// Where the pipeline's messages go, after Drake's lcm/ (DrakeLcmInterface with its live, log and in-memory
// implementations): one interface, so the daemon, `noisemon replay` and the tests run the same pipeline into the
// LCM bus (lcm_publisher.hpp), an LCM log file (log_publisher.hpp), a CSV file of the cycle reports
// (csv_publisher.hpp) or memory (memory_publisher.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
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
// the event with. A failure throws (it fails the publishing thread, and the pipeline says why).
//
// One byte-level publish, as Drake's DrakeLcmInterface::Publish: a message arrives encoded (its LCM type's
// fingerprint first), so a new message type needs no change here or in any publisher; the typed publish on top
// encodes once. Publishers that keep only some types (CSV, HDF5) pick them out with decode_as.
class Publisher {
 public:
  virtual ~Publisher() = default;
  virtual void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                             std::int64_t utime) = 0;
  // The run the following cycle reports belong to (session_t::condition; "" when unknown): replay starts one per
  // session of a log, before its pipeline publishes. Files that keep runs apart (CSV, HDF5) mark them.
  virtual void begin_run(const std::string& /*condition*/) {}
  // Makes what was published so far durable (files written out); the pipeline calls it when it stops.
  virtual void flush() {}
  // What a publisher with a state of its own (the recorder) adds to the daemon's status message: threads, rings,
  // counters. Called on the publishing thread before each status is published.
  virtual void add_status(noisemon::status_t& /*status*/) const {}

  // Any LCM message type of msgs/ (noisemon::cycle_report_t, status_t, ...).
  template <class Message>
  void publish(const std::string& channel, const Message& m, std::int64_t utime) {
    encoded_.resize(static_cast<std::size_t>(m.getEncodedSize()));
    if (m.encode(encoded_.data(), 0, static_cast<int>(encoded_.size())) != static_cast<int>(encoded_.size()))
      throw std::runtime_error("cannot encode a message for channel " + channel);
    publish_bytes(channel, encoded_.data(), encoded_.size(), utime);
  }

 private:
  std::vector<std::uint8_t> encoded_;  // reused: no allocation per message once warm
};

// The message an encoded one holds if it is of type Message (its fingerprint says), else nothing.
template <class Message>
[[nodiscard]] std::optional<Message> decode_as(const std::uint8_t* data, std::size_t size) {
  Message m;
  if (m.decode(data, 0, static_cast<int>(size)) < 0) return std::nullopt;
  return m;
}

// Every message to each of several publishers, in the order they were added.
class FanoutPublisher final : public Publisher {
 public:
  void add(std::shared_ptr<Publisher> publisher) { publishers_.push_back(std::move(publisher)); }
  [[nodiscard]] bool empty() const { return publishers_.empty(); }

  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override {
    for (const auto& p : publishers_) p->publish_bytes(channel, data, size, utime);
  }
  void begin_run(const std::string& condition) override {
    for (const auto& p : publishers_) p->begin_run(condition);
  }
  void flush() override {
    for (const auto& p : publishers_) p->flush();
  }
  void add_status(noisemon::status_t& status) const override {
    for (const auto& p : publishers_) p->add_status(status);
  }

 private:
  std::vector<std::shared_ptr<Publisher>> publishers_;
};

}  // namespace noisemon::daemon
