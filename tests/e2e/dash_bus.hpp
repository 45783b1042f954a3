// What the dashboard test hears on the bus itself: the cycle reports (by channel, keyed by their utime) and the
// status messages, to compare with what the page and /metrics show.
#pragma once

#include <poll.h>

#include <atomic>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "noisemon/cycle_report_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::test {

class BusRecorder {
 public:
  BusRecorder(const std::string& url, const std::vector<std::string>& cycle_channels, const std::string& status_channel)
      : lcm_(url) {
    for (const auto& c : cycle_channels) lcm_.subscribe(c, &BusRecorder::on_cycle, this);
    lcm_.subscribe(status_channel, &BusRecorder::on_status, this);
    thread_ = std::thread([this] {
      while (!stop_) {
        pollfd p{lcm_.getFileno(), POLLIN, 0};
        if (poll(&p, 1, 50) > 0) lcm_.handle();
      }
    });
  }
  ~BusRecorder() {
    stop_ = true;
    thread_.join();
  }
  bool good() { return lcm_.good(); }

  std::optional<noisemon::cycle_report_t> cycle_at(std::int64_t utime) {
    std::lock_guard lock(mutex_);
    for (const auto& [channel, cycles] : cycles_)
      if (const auto it = cycles.find(utime); it != cycles.end()) return it->second;
    return std::nullopt;
  }
  // The newest report of a channel with this cycle index.
  std::optional<noisemon::cycle_report_t> newest_with_index(const std::string& channel, std::int64_t index) {
    std::lock_guard lock(mutex_);
    std::optional<noisemon::cycle_report_t> found;
    for (const auto& [utime, r] : cycles_[channel])
      if (r.cycle == index) found = r;
    return found;
  }
  std::map<std::int64_t, noisemon::cycle_report_t> cycles(const std::string& channel) {
    std::lock_guard lock(mutex_);
    return cycles_[channel];
  }
  std::vector<noisemon::status_t> statuses() {
    std::lock_guard lock(mutex_);
    return statuses_;
  }

 private:
  void on_cycle(const lcm::ReceiveBuffer*, const std::string& channel, const noisemon::cycle_report_t* r) {
    std::lock_guard lock(mutex_);
    cycles_[channel][r->utime] = *r;
  }
  void on_status(const lcm::ReceiveBuffer*, const std::string&, const noisemon::status_t* s) {
    std::lock_guard lock(mutex_);
    statuses_.push_back(*s);
  }

  lcm::LCM lcm_;
  std::mutex mutex_;
  std::map<std::string, std::map<std::int64_t, noisemon::cycle_report_t>> cycles_;
  std::vector<noisemon::status_t> statuses_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace noisemon::test
