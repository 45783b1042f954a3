// The instants the crank passes one angle (a sync pulse's angle), on the pipeline's time base: written by the
// thread that reads the crank angle (the pipeline), read by a microphone front-end's thread that matches its sync
// pulses to them (drivers/aligned_stream.hpp). A mutex guards a short history; both sides touch it a few times per
// revolution.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>

#include "drivers/source.hpp"

namespace noisemon::drivers {

class CrankReference {
 public:
  // angle_deg: the crank angle of the pulse, degrees after firing TDC on the stream's scale; it is passed once a
  // revolution (angle_deg and angle_deg + 360 of each 720-degree cycle).
  explicit CrankReference(double angle_deg) : angle_deg_(std::fmod(std::fmod(angle_deg, 360.0) + 360.0, 360.0)) {}

  [[nodiscard]] double angle_deg() const { return angle_deg_; }

  // The pipeline's side: each pressure block's crank channel; an instant is posted where the angle passes
  // angle_deg (mod 360) between two frames with known angles, interpolated between them.
  void add_crank(const SampleBlock& block) {
    for (std::uint32_t f = 0; f < block.frames; ++f) {
      const double a = block.data[static_cast<std::size_t>(f) * block.channels + kCrankChannel];
      const double frame = static_cast<double>(block.first_index + f);
      if (std::isfinite(a) && std::isfinite(previous_angle_) && frame == previous_frame_ + 1.0) {
        // Relative to the pulse's angle in [0, 360): passing it wraps from near 360 to near 0, a forward step.
        const double from = unwrap(previous_angle_), to = unwrap(a);
        const double step = to + 360.0 - from;
        if (to < from && step < 90.0) post((previous_frame_ + (360.0 - from) / step) / kPipelineRateHz);
      }
      previous_angle_ = a;
      previous_frame_ = frame;
    }
  }
  // An instant (s since the stream's epoch) the crank passed the angle.
  void post(double t_s) {
    std::lock_guard<std::mutex> lock(mutex_);
    instants_.push_back(t_s);
    while (instants_.size() > kHistory) instants_.pop_front();
  }

  struct Match {
    double instant_s = NAN;     // the nearest posted instant
    double latest_s = NAN;      // the latest posted instant (NaN: none yet)
    double revolution_s = NAN;  // the time between the two instants around the match
  };
  // The posted instant nearest to t_s.
  [[nodiscard]] Match nearest(double t_s) const {
    std::lock_guard<std::mutex> lock(mutex_);
    Match m;
    if (instants_.empty()) return m;
    m.latest_s = instants_.back();
    std::size_t best = 0;
    for (std::size_t i = 1; i < instants_.size(); ++i)
      if (std::abs(instants_[i] - t_s) < std::abs(instants_[best] - t_s)) best = i;
    m.instant_s = instants_[best];
    if (instants_.size() >= 2)
      m.revolution_s = best > 0 ? instants_[best] - instants_[best - 1] : instants_[1] - instants_[0];
    return m;
  }

 private:
  static constexpr std::size_t kHistory = 256;
  // The angle relative to the pulse's, in [0, 360).
  double unwrap(double a) const { return std::fmod(std::fmod(a - angle_deg_, 360.0) + 360.0, 360.0); }

  double angle_deg_;
  double previous_angle_ = NAN, previous_frame_ = NAN;
  mutable std::mutex mutex_;
  std::deque<double> instants_;
};

}  // namespace noisemon::drivers
