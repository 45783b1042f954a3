// The log publisher: messages as events of an LCM log file (the lcm-logger format, readable by lcm-logplayer,
// lcm-spy and `noisemon watch --lcm file://...`), each stamped with the instant it stands for. `noisemon replay
// --out` writes its cycle reports with it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "daemon/publisher.hpp"

namespace lcm {
class LogFile;
}

namespace noisemon::daemon {

class LogPublisher final : public Publisher {
 public:
  // Creates (replaces) the file; throws std::runtime_error naming it when it cannot. channels: the only channels
  // written (e.g. the cycle reports alone); empty: every channel.
  explicit LogPublisher(const std::string& path, std::vector<std::string> channels = {});
  ~LogPublisher() override;

  void publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::status_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::session_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::raw_block_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::operating_point_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::cycle_stats_t& m, std::int64_t utime) override;
  void flush() override;

 private:
  template <class Message>
  void write(const std::string& channel, const Message& m, std::int64_t utime);

  std::string path_;
  std::vector<std::string> channels_;
  std::unique_ptr<lcm::LogFile> log_;
  std::vector<char> encoded_;  // reused for every event
};

}  // namespace noisemon::daemon
