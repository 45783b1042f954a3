// The resamplers' output: frames delivered into the caller's buffer, those that do not fit kept for the next call
// (a fixed ring: no allocation after construction). Internal to dsp/.
#pragma once

#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace noisemon::dsp {

// Delivers output frames into the caller's buffer; what does not fit is kept for the next call.
class OutputQueue {
 public:
  OutputQueue(std::size_t channels, std::size_t capacity_frames)
      : channels_(channels), capacity_(capacity_frames), ring_(channels * capacity_frames) {}

  // Starts a call: pending frames go out first.
  void begin(double* out, std::size_t max_out) {
    out_ = out;
    max_out_ = max_out;
    written_ = 0;
    while (count_ > 0 && written_ < max_out_) {
      std::memcpy(out_ + written_ * channels_, &ring_[head_ * channels_], channels_ * sizeof(double));
      head_ = (head_ + 1) % capacity_;
      --count_;
      ++written_;
    }
  }
  // Where the next frame goes (channels values).
  double* next_slot() {
    if (count_ == 0 && written_ < max_out_) return out_ + (written_++) * channels_;
    if (count_ == capacity_)
      throw std::length_error("resampler: more than " + std::to_string(capacity_) +
                              " output frames pending; call process() with more room in out");
    double* slot = &ring_[((head_ + count_) % capacity_) * channels_];
    ++count_;
    return slot;
  }
  // Appends `frames` frames of channels values each.
  void push(const double* frames, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i)
      std::memcpy(next_slot(), frames + i * channels_, channels_ * sizeof(double));
  }
  std::size_t written() const { return written_; }
  std::size_t pending() const { return count_; }

 private:
  std::size_t channels_;
  std::size_t capacity_;
  std::vector<double> ring_;
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  double* out_ = nullptr;
  std::size_t max_out_ = 0;
  std::size_t written_ = 0;
};

}  // namespace noisemon::dsp
