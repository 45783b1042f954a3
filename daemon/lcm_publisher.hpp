// The live publisher: every message on the LCM bus (what noisemond does).
#pragma once

#include <memory>
#include <string>

#include "daemon/publisher.hpp"

namespace lcm {
class LCM;
}

namespace noisemon::daemon {

class LcmPublisher final : public Publisher {
 public:
  // url: empty for LCM's default. Throws std::runtime_error when LCM cannot start (no multicast route).
  explicit LcmPublisher(const std::string& url);
  ~LcmPublisher() override;

  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override;

 private:
  std::unique_ptr<lcm::LCM> lcm_;
};

}  // namespace noisemon::daemon
