// A bounded queue of LCM events (channel, stamp, encoded bytes) from one thread to another, over a lock-free byte
// ring (dsp/spsc_ring.hpp): the recorder's buffer between the publishing thread and its writer. Its bytes are
// reserved once; the producer never blocks or waits, and an event that does not fit whole is refused whole.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "dsp/spsc_ring.hpp"

namespace noisemon::daemon {

// An event as the consumer takes it out; its storage is reused from one pop to the next.
struct QueuedEvent {
  std::int64_t utime = 0;
  std::string channel;
  std::vector<std::uint8_t> data;
};

class EventQueue {
 public:
  // capacity_bytes: rounded up to a power of two; each event takes 16 bytes more than its channel and data.
  explicit EventQueue(std::size_t capacity_bytes) : ring_(capacity_bytes) {}

  // Producer: copies the event in whole, or nothing (false) when it does not fit now.
  [[nodiscard]] bool push(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime) {
    const std::size_t total = sizeof(Header) + channel.size() + size;
    if (total > ring_.capacity() || ring_.capacity() - ring_.size() < total) return false;
    const Header h{utime, static_cast<std::uint32_t>(channel.size()), static_cast<std::uint32_t>(size)};
    staging_.resize(total);  // grows to the largest event once: one write keeps an event whole
    std::memcpy(staging_.data(), &h, sizeof h);
    std::memcpy(staging_.data() + sizeof h, channel.data(), channel.size());
    if (size > 0) std::memcpy(staging_.data() + sizeof h + channel.size(), data, size);
    return ring_.write(staging_.data(), total);
  }

  // Consumer: the oldest event, or false when there is none.
  [[nodiscard]] bool pop(QueuedEvent& out) {
    Header h{};
    if (ring_.peek(reinterpret_cast<std::uint8_t*>(&h), sizeof h) != sizeof h) return false;
    ring_.consume(sizeof h);  // the producer wrote the event in one piece: the rest is there
    out.utime = h.utime;
    out.channel.resize(h.channel_size);
    (void)ring_.read(reinterpret_cast<std::uint8_t*>(out.channel.data()), h.channel_size);
    out.data.resize(h.data_size);
    (void)ring_.read(out.data.data(), h.data_size);
    return true;
  }

  [[nodiscard]] bool empty() const { return ring_.empty(); }
  [[nodiscard]] std::size_t capacity_bytes() const { return ring_.capacity(); }
  [[nodiscard]] double fill_fraction() const { return ring_.fill_fraction(); }

 private:
  struct Header {
    std::int64_t utime;
    std::uint32_t channel_size, data_size;
  };
  dsp::SpscRing<std::uint8_t> ring_;
  std::vector<std::uint8_t> staging_;  // the producer's
};

}  // namespace noisemon::daemon
