#include "daemon/angle_cycles.hpp"

#include <algorithm>
#include <cmath>

namespace noisemon::daemon {

AngleCycles::AngleCycles(double step_deg, double horizon_frames)
    : step_deg_(step_deg), horizon_frames_(horizon_frames), open_(step_deg) {}

void AngleCycles::add(const drivers::SampleBlock& block) {
  if (block.frames == 0) return;
  const auto at = static_cast<double>(block.first_index);  // at or before each of its edges
  for (std::uint32_t f = 0; f < block.frames; ++f) {
    const double* e = block.data + static_cast<std::size_t>(f) * block.channels;
    edge(at, e[drivers::kAngleCrankChannel], e[drivers::kAnglePressureChannel]);
  }
  covered_until_ = std::max(covered_until_, block.first_index);
}

void AngleCycles::edge(double t, double crank_deg, double pressure_pa) {
  if (!std::isfinite(crank_deg)) {
    open_.break_line();
    return;
  }
  if (has_last_ && crank_deg < last_deg_ - 360.0) {
    wrap(t, crank_deg, pressure_pa);
  } else {
    if (has_last_ && !(crank_deg > last_deg_ && crank_deg - last_deg_ <= kMaxStepsBridged * step_deg_))
      open_.break_line();
    open_.add(crank_deg, pressure_pa);
  }
  last_deg_ = crank_deg;
  has_last_ = true;
}

// The edge that opens the next cycle closes the open one; the next grid starts on the edges' own angles.
void AngleCycles::wrap(double t, double crank_deg, double pressure_pa) {
  if (crank_deg + 720.0 - last_deg_ > kMaxStepsBridged * step_deg_) open_.break_line();
  open_.close(crank_deg, pressure_pa);
  if (open_valid_) {
    Completed c{spare_.empty() ? Completed{CrankGrid(step_deg_), 0.0} : std::move(spare_.back())};
    if (!spare_.empty()) spare_.pop_back();
    c.grid = open_;  // a copy into the reused grid's storage
    c.closed_at = t;
    completed_.push_back(std::move(c));
    const auto expired = std::find_if(completed_.begin(), completed_.end(),
                                      [&](const Completed& k) { return k.closed_at >= t - horizon_frames_; });
    for (auto it = completed_.begin(); it != expired; ++it) recycle(std::move(*it));
    completed_.erase(completed_.begin(), expired);
  }
  open_valid_ = true;
  const double from_start = crank_deg + 360.0;
  open_.reopen(-360.0 + from_start - step_deg_ * std::floor(from_start / step_deg_ + 1e-9));
  open_.add(crank_deg, pressure_pa);
}

CrankGrid* AngleCycles::take(std::int64_t boundary, double tolerance_frames) {
  if (taken_) recycle(std::move(*taken_));
  taken_.reset();
  const auto b = static_cast<double>(boundary);
  auto it = completed_.begin();
  for (; it != completed_.end() && it->closed_at < b - tolerance_frames; ++it) recycle(std::move(*it));
  if (it != completed_.end() && it->closed_at <= b + tolerance_frames) taken_ = std::move(*it++);
  completed_.erase(completed_.begin(), it);
  return taken_ ? &taken_->grid : nullptr;
}

}  // namespace noisemon::daemon
