// The in-memory publisher: keeps every message with its channel and instant, for tests of the pipeline (the
// in-memory implementation of Drake's lcm/ pattern). Safe to read from another thread while a pipeline publishes.
#pragma once

#include <mutex>
#include <string>
#include <vector>

#include "daemon/publisher.hpp"

namespace noisemon::daemon {

template <class Message>
struct Published {
  std::string channel;
  Message message;
  std::int64_t utime = 0;
};

class MemoryPublisher final : public Publisher {
 public:
  void publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t utime) override {
    keep(reports_, channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::status_t& m, std::int64_t utime) override {
    keep(statuses_, channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::session_t& m, std::int64_t utime) override {
    keep(sessions_, channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::raw_block_t& m, std::int64_t utime) override {
    keep(raw_blocks_, channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::operating_point_t& m, std::int64_t utime) override {
    keep(operating_points_, channel, m, utime);
  }
  void publish(const std::string& channel, const noisemon::cycle_stats_t& m, std::int64_t utime) override {
    keep(statistics_, channel, m, utime);
  }

  // Copies of what was published so far, in order.
  std::vector<Published<noisemon::cycle_report_t>> reports() const { return copy(reports_); }
  std::vector<Published<noisemon::status_t>> statuses() const { return copy(statuses_); }
  std::vector<Published<noisemon::session_t>> sessions() const { return copy(sessions_); }
  std::vector<Published<noisemon::raw_block_t>> raw_blocks() const { return copy(raw_blocks_); }
  std::vector<Published<noisemon::operating_point_t>> operating_points() const { return copy(operating_points_); }
  std::vector<Published<noisemon::cycle_stats_t>> statistics() const { return copy(statistics_); }

 private:
  template <class Message>
  void keep(std::vector<Published<Message>>& to, const std::string& channel, const Message& m, std::int64_t utime) {
    std::lock_guard lock(mutex_);
    to.push_back({channel, m, utime});
  }
  template <class Message>
  std::vector<Published<Message>> copy(const std::vector<Published<Message>>& from) const {
    std::lock_guard lock(mutex_);
    return from;
  }

  mutable std::mutex mutex_;
  std::vector<Published<noisemon::cycle_report_t>> reports_;
  std::vector<Published<noisemon::status_t>> statuses_;
  std::vector<Published<noisemon::session_t>> sessions_;
  std::vector<Published<noisemon::raw_block_t>> raw_blocks_;
  std::vector<Published<noisemon::operating_point_t>> operating_points_;
  std::vector<Published<noisemon::cycle_stats_t>> statistics_;
};

}  // namespace noisemon::daemon
