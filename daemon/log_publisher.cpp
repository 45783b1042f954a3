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

template <class Message>
void LogPublisher::write(const std::string& channel, const Message& m, std::int64_t utime) {
  if (!channels_.empty() && std::find(channels_.begin(), channels_.end(), channel) == channels_.end()) return;
  encoded_.resize(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(encoded_.data(), 0, static_cast<int>(encoded_.size()));
  lcm::LogEvent e{0, utime, channel, static_cast<std::int32_t>(encoded_.size()), encoded_.data()};
  if (log_->writeEvent(&e) != 0) throw std::runtime_error(path_ + ": cannot write log event (disk full?)");
}

void LogPublisher::publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t utime) {
  write(channel, m, utime);
}
void LogPublisher::publish(const std::string& channel, const noisemon::status_t& m, std::int64_t utime) {
  write(channel, m, utime);
}
void LogPublisher::publish(const std::string& channel, const noisemon::session_t& m, std::int64_t utime) {
  write(channel, m, utime);
}
void LogPublisher::publish(const std::string& channel, const noisemon::raw_block_t& m, std::int64_t utime) {
  write(channel, m, utime);
}
void LogPublisher::publish(const std::string& channel, const noisemon::operating_point_t& m, std::int64_t utime) {
  write(channel, m, utime);
}
void LogPublisher::publish(const std::string& channel, const noisemon::cycle_stats_t& m, std::int64_t utime) {
  write(channel, m, utime);
}

void LogPublisher::flush() {
  if (std::fflush(log_->getFilePtr()) != 0) throw std::runtime_error(path_ + ": cannot write log file (disk full?)");
}

}  // namespace noisemon::daemon
