#include "cli/dash_state.hpp"

#include "cli/dash_json.hpp"
#include "cli/dash_metrics.hpp"

namespace noisemon::cli {

DashState::DashState(std::string cell, std::size_t history_cycles, nlohmann::json reference)
    : cell_(std::move(cell)), history_cycles_(history_cycles), reference_(std::move(reference)) {}

void DashState::on_cycle(const noisemon::cycle_report_t& r) {
  nlohmann::json cycle = cycle_json(r);  // built outside the lock: the HTTP threads wait less
  std::lock_guard lock(mutex_);
  // A cycle index that goes back means the daemon restarted; one that jumps means cycles were dropped.
  const bool restarted = last_cycle_ && r.cycle <= last_cycle_->cycle;
  const std::int64_t dropped = last_cycle_ && !restarted ? r.cycle - last_cycle_->cycle - 1 : 0;
  trend_.emplace_back(++sequence_, trend_point_json(r, dropped, restarted));
  while (trend_.size() > history_cycles_) trend_.pop_front();
  cycle_ = std::move(cycle);
  last_cycle_ = r;
  changed_.notify_all();
}

void DashState::on_status(const noisemon::status_t& s) {
  nlohmann::json status = status_json(s);
  std::lock_guard lock(mutex_);
  status_ = std::move(status);
  last_status_ = s;
  status_received_ = std::chrono::steady_clock::now();
}

void DashState::on_operating_point(const noisemon::operating_point_t& op) {
  nlohmann::json json = operating_point_json(op);
  std::lock_guard lock(mutex_);
  operating_point_ = std::move(json);
}

void DashState::on_gap_event(const noisemon::gap_event_t& e) {
  nlohmann::json json = gap_event_json(e);
  std::lock_guard lock(mutex_);
  gap_events_.push_back(std::move(json));
  while (gap_events_.size() > 100) gap_events_.pop_front();
  ++gap_events_by_effect_[e.effect];
}

void DashState::on_gap_status(const noisemon::gap_status_t& s) {
  nlohmann::json json = gap_status_json(s);
  std::lock_guard lock(mutex_);
  gap_status_ = std::move(json);
  last_gap_status_ = s;
}

void DashState::on_check(const noisemon::check_t& c) {
  nlohmann::json json = check_json(c);
  std::lock_guard lock(mutex_);
  check_ = std::move(json);
  last_check_ = c;
  ++checks_;
  changed_.notify_all();
}

std::uint64_t DashState::checks() const {
  std::lock_guard lock(mutex_);
  return checks_;
}

std::uint64_t DashState::sequence() const {
  std::lock_guard lock(mutex_);
  return sequence_;
}

std::uint64_t DashState::wait_newer(std::uint64_t after, std::chrono::milliseconds timeout, std::uint64_t checks_seen) {
  std::unique_lock lock(mutex_);
  changed_.wait_for(lock, timeout, [&] { return stopped_ || sequence_ > after || checks_ > checks_seen; });
  return sequence_;
}

void DashState::stop() {
  std::lock_guard lock(mutex_);
  stopped_ = true;
  changed_.notify_all();
}

bool DashState::stopped() const {
  std::lock_guard lock(mutex_);
  return stopped_;
}

nlohmann::json DashState::snapshot_locked(std::uint64_t after) const {
  nlohmann::json trend = nlohmann::json::array();
  for (const auto& [seq, point] : trend_)
    if (seq > after) trend.push_back(point);
  nlohmann::json snapshot = {{"cell", cell_},
                             {"seq", sequence_},
                             {"history", history_cycles_},
                             {"full", after == 0},
                             {"cycle", cycle_},
                             {"status", status_},
                             {"op", operating_point_},
                             {"trend", std::move(trend)},
                             {"gap_status", gap_status_},
                             {"gap_events", nlohmann::json(gap_events_)},
                             {"check", check_}};
  if (after == 0) snapshot["reference"] = reference_;
  return snapshot;
}

std::string DashState::event_json(std::uint64_t after, std::uint64_t& sent) const {
  std::lock_guard lock(mutex_);
  sent = sequence_;
  return snapshot_locked(after).dump();
}

std::string DashState::state_json() const {
  std::lock_guard lock(mutex_);
  return snapshot_locked(0).dump();
}

std::string DashState::metrics_text() const {
  MetricsInput in;
  {
    std::lock_guard lock(mutex_);
    in.cell = cell_;
    in.status = last_status_;
    in.cycle = last_cycle_;
    in.gap_status = last_gap_status_;
    in.gap_events_by_effect = gap_events_by_effect_;
    in.check = last_check_;
    in.cycles_received = static_cast<long long>(sequence_);
    in.status_age_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - status_received_).count();
  }
  return prometheus_text(in);
}

}  // namespace noisemon::cli
