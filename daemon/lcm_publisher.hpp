// The live publisher: the messages on the LCM bus (what noisemond does), all but those of channels it is told to
// keep off it (the raw streams when only the recorder wants them).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "daemon/publisher.hpp"

namespace lcm {
class LCM;
}

namespace noisemon::daemon {

class LcmPublisher final : public Publisher {
 public:
  // url: empty for LCM's default. Throws std::runtime_error when LCM cannot start (no multicast route).
  explicit LcmPublisher(const std::string& url, std::vector<std::string> kept_off = {});
  ~LcmPublisher() override;

  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override;

 private:
  std::unique_ptr<lcm::LCM> lcm_;
  std::vector<std::string> kept_off_;
};

}  // namespace noisemon::daemon
