// The in-memory publisher: keeps every message with its channel and instant, for tests of the pipeline (the
// in-memory implementation of Drake's lcm/ pattern). Safe to read from another thread while a pipeline publishes.
#pragma once

#include <cstdint>
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
  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override {
    std::lock_guard lock(mutex_);
    kept_.push_back({channel, std::vector<std::uint8_t>(data, data + size), utime});
  }

  // What was published so far of one message type, in order (each message decoded as it is asked for).
  template <class Message>
  [[nodiscard]] std::vector<Published<Message>> messages() const {
    std::lock_guard lock(mutex_);
    std::vector<Published<Message>> out;
    for (const Encoded& e : kept_)
      if (auto m = decode_as<Message>(e.bytes.data(), e.bytes.size()))
        out.push_back({e.channel, std::move(*m), e.utime});
    return out;
  }
  [[nodiscard]] auto reports() const { return messages<noisemon::cycle_report_t>(); }
  [[nodiscard]] auto statuses() const { return messages<noisemon::status_t>(); }
  [[nodiscard]] auto sessions() const { return messages<noisemon::session_t>(); }
  [[nodiscard]] auto raw_blocks() const { return messages<noisemon::raw_block_t>(); }
  [[nodiscard]] auto operating_points() const { return messages<noisemon::operating_point_t>(); }
  [[nodiscard]] auto statistics() const { return messages<noisemon::cycle_stats_t>(); }

 private:
  struct Encoded {
    std::string channel;
    std::vector<std::uint8_t> bytes;
    std::int64_t utime = 0;
  };
  mutable std::mutex mutex_;
  std::vector<Encoded> kept_;
};

}  // namespace noisemon::daemon
