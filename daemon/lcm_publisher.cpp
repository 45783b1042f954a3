#include "daemon/lcm_publisher.hpp"

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <stdexcept>

namespace noisemon::daemon {

LcmPublisher::LcmPublisher(const std::string& url, std::vector<std::string> kept_off)
    : lcm_(std::make_unique<lcm::LCM>(url)), kept_off_(std::move(kept_off)) {
  if (!lcm_->good())
    throw std::runtime_error("cannot open LCM at '" + (url.empty() ? std::string("default URL") : url) +
                             "': the network needs a multicast route (see README, 'LCM and multicast')");
}

LcmPublisher::~LcmPublisher() = default;

// The bus stamps its own time: utime is for logs.
void LcmPublisher::publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size, std::int64_t) {
  if (std::find(kept_off_.begin(), kept_off_.end(), channel) != kept_off_.end()) return;
  lcm_->publish(channel, data, static_cast<unsigned int>(size));
}

}  // namespace noisemon::daemon
