// `noisemon dash`: what the dashboard knows, shared between the LCM thread that fills it and the HTTP threads that
// read it: the last cycle, status and operating point, and a rolling history of trend points.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "noisemon/check_t.hpp"
#include "noisemon/cycle_report_t.hpp"
#include "noisemon/gap_event_t.hpp"
#include "noisemon/gap_status_t.hpp"
#include "noisemon/operating_point_t.hpp"
#include "noisemon/status_t.hpp"

namespace noisemon::cli {

class DashState {
 public:
  // reference: a curve sent once with each client's first event (the thesis's linear attenuation curve).
  DashState(std::string cell, std::size_t history_cycles, nlohmann::json reference = {});

  void on_cycle(const noisemon::cycle_report_t& r);
  void on_status(const noisemon::status_t& s);
  void on_operating_point(const noisemon::operating_point_t& op);
  // noisemon gapwatch's events (the last 100 kept: the page's timeline) and state.
  void on_gap_event(const noisemon::gap_event_t& e);
  void on_gap_status(const noisemon::gap_status_t& s);
  // noisemon check --publish's table (the newest kept).
  void on_check(const noisemon::check_t& c);

  // Number of cycle reports received so far (the sequence of the newest one).
  std::uint64_t sequence() const;
  // Number of check tables received so far (they come while no cycle does: before the engine starts).
  std::uint64_t checks() const;
  // Waits until a cycle newer than `after` or a check table after the `checks_seen`th arrives, `timeout` passes or
  // stop() is called; returns sequence().
  std::uint64_t wait_newer(std::uint64_t after, std::chrono::milliseconds timeout, std::uint64_t checks_seen = 0);
  // Wakes every waiter for good (shutdown).
  void stop();
  bool stopped() const;

  // One server-sent event's data: the newest cycle, status and operating point, and the trend points newer than
  // `after` (those the client has not had yet); `sent` receives the sequence it covers. The first (after == 0)
  // also carries the reference curve.
  std::string event_json(std::uint64_t after, std::uint64_t& sent) const;
  // /api/state: the same with the whole history.
  std::string state_json() const;
  // /metrics.
  std::string metrics_text() const;

 private:
  nlohmann::json snapshot_locked(std::uint64_t after) const;

  const std::string cell_;
  const std::size_t history_cycles_;
  const nlohmann::json reference_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool stopped_ = false;
  std::uint64_t sequence_ = 0;
  std::deque<std::pair<std::uint64_t, nlohmann::json>> trend_;  // (sequence, point), oldest first
  nlohmann::json cycle_, status_, operating_point_;
  std::optional<noisemon::cycle_report_t> last_cycle_;
  std::optional<noisemon::status_t> last_status_;
  std::deque<nlohmann::json> gap_events_;
  std::map<std::string, long long> gap_events_by_effect_;
  nlohmann::json gap_status_;
  std::optional<noisemon::gap_status_t> last_gap_status_;
  nlohmann::json check_;
  std::uint64_t checks_ = 0;
  std::optional<noisemon::check_t> last_check_;
  std::chrono::steady_clock::time_point status_received_;
};

}  // namespace noisemon::cli
