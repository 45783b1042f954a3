#include "daemon/log_publisher.hpp"

#include <algorithm>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

namespace noisemon::daemon {

LogPublisher::LogPublisher(const std::string& path, std::vector<std::string> channels)
    : path_(path), channels_(std::move(channels)), log_(std::make_unique<lcm::LogFile>(path, "w")) {
  if (!log_->good()) throw std::runtime_error(path + ": cannot write log file");
}

LogPublisher::~LogPublisher() = default;

void LogPublisher::publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                                 std::int64_t utime) {
  if (!channels_.empty() && std::find(channels_.begin(), channels_.end(), channel) == channels_.end()) return;
  // lcm::LogEvent's data is not const; writeEvent only reads it.
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(size), const_cast<std::uint8_t*>(data)};
  if (log_->writeEvent(&e) != 0) throw std::runtime_error(path_ + ": cannot write log event (disk full?)");
}

void LogPublisher::flush() {
  if (std::fflush(log_->getFilePtr()) != 0) throw std::runtime_error(path_ + ": cannot write log file (disk full?)");
}

}  // namespace noisemon::daemon
