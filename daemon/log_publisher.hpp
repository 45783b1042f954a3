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

  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override;
  void flush() override;

 private:
  std::string path_;
  std::vector<std::string> channels_;
  std::unique_ptr<lcm::LogFile> log_;
};

}  // namespace noisemon::daemon
