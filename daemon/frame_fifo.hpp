// A preallocated FIFO of multichannel frames indexed by their position on the 40 kHz grid.
// Used by the processing thread only (single-threaded): it keeps each stream's recent frames until the other
// streams catch up, so frames of one instant can be combined. Gaps in the index are filled by holding the
// last frame (zeros at the start) and reported to the caller. It never grows and never throws: when the other
// streams stall for longer than it holds, its oldest frames are dropped; a gap longer than it holds restarts it
// at the new frames. Both are reported, so the caller can drop the cycles they touch.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace noisemon::daemon {

class FrameFifo {
 public:
  // capacity_frames is rounded up to a power of two (indexing by mask, not division).
  FrameFifo(std::size_t channels, std::size_t capacity_frames)
      : channels_(channels),
        capacity_(round_up_pow2(capacity_frames)),
        mask_(capacity_ - 1),
        data_(channels * capacity_, 0.0),
        last_(channels, 0.0) {}

  std::size_t channels() const { return channels_; }
  bool started() const { return started_; }
  std::int64_t begin_index() const { return begin_; }  // index of the oldest frame held
  std::int64_t end_index() const { return begin_ + static_cast<std::int64_t>(size_); }  // one past the newest
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return capacity_; }

  struct Appended {
    std::size_t held = 0;     // frames filled in by holding the last frame (a gap shorter than the capacity)
    std::size_t dropped = 0;  // frames lost unconsumed: the oldest ones, pushed out, or all of them on a restart
    bool restarted = false;   // the gap before `first` was longer than the capacity: the FIFO now begins there
  };

  // Appends frames whose first frame has grid index `first`. Frames already present are skipped.
  Appended append(std::int64_t first, const double* frames, std::size_t n) {
    Appended a;
    if (!started_) {
      begin_ = first;
      started_ = true;
    }
    const std::int64_t end = end_index();
    if (first - end >= static_cast<std::int64_t>(capacity_)) {
      a.dropped = size_;
      a.restarted = true;
      head_ = size_ = 0;
      begin_ = first;
    } else if (first > end) {
      a.held = static_cast<std::size_t>(first - end);
      for (std::size_t i = 0; i < a.held; ++i) a.dropped += push(last_.data());
    }
    std::size_t skip =
        first < end_index() ? static_cast<std::size_t>(std::min<std::int64_t>(end_index() - first, n)) : 0;
    std::size_t count = n - skip;
    if (count == 0) return a;
    if (count > capacity_) {  // more new frames than it holds: keep the newest, beginning where they begin
      a.dropped += size_ + (count - capacity_);
      a.restarted = true;
      skip = n - capacity_;
      count = capacity_;
      head_ = size_ = 0;
      begin_ = first + static_cast<std::int64_t>(skip);
    }
    if (size_ + count > capacity_) a.dropped += drop_oldest(size_ + count - capacity_);
    const double* src = frames + skip * channels_;
    const std::size_t pos = (head_ + size_) & mask_;
    const std::size_t first_part = std::min(count, capacity_ - pos);
    std::copy(src, src + first_part * channels_, &data_[pos * channels_]);
    std::copy(src + first_part * channels_, src + count * channels_, data_.begin());
    std::copy(src + (count - 1) * channels_, src + count * channels_, last_.begin());
    size_ += count;
    return a;
  }
  // Pointer to the frame with grid index `index` (must be within [begin_index, end_index)).
  const double* frame(std::int64_t index) const {
    const std::size_t pos = (head_ + static_cast<std::size_t>(index - begin_)) & mask_;
    return &data_[pos * channels_];
  }
  // Drops every frame with index < `index`.
  void drop_before(std::int64_t index) {
    if (index <= begin_) return;
    drop_oldest(static_cast<std::size_t>(std::min<std::int64_t>(index - begin_, static_cast<std::int64_t>(size_))));
    if (size_ == 0) begin_ = index;
  }

 private:
  std::size_t drop_oldest(std::size_t n) {
    head_ = (head_ + n) & mask_;
    size_ -= n;
    begin_ += static_cast<std::int64_t>(n);
    return n;
  }
  // Appends one frame; returns how many old frames it pushed out (0 or 1).
  std::size_t push(const double* f) {
    const std::size_t out = size_ == capacity_ ? drop_oldest(1) : 0;
    const std::size_t pos = (head_ + size_) & mask_;
    std::copy(f, f + channels_, &data_[pos * channels_]);
    std::copy(f, f + channels_, last_.begin());
    ++size_;
    return out;
  }

  static std::size_t round_up_pow2(std::size_t n) {
    std::size_t p = 1;
    while (p < n) p <<= 1;
    return p;
  }

  std::size_t channels_, capacity_, mask_;
  std::vector<double> data_;
  std::vector<double> last_;
  std::size_t head_ = 0, size_ = 0;
  std::int64_t begin_ = 0;
  bool started_ = false;
};

}  // namespace noisemon::daemon
