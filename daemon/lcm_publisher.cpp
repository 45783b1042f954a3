#include "daemon/lcm_publisher.hpp"

#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

namespace noisemon::daemon {

LcmPublisher::LcmPublisher(const std::string& url) : lcm_(std::make_unique<lcm::LCM>(url)) {
  if (!lcm_->good())
    throw std::runtime_error("cannot open LCM at '" + (url.empty() ? std::string("default URL") : url) +
                             "': the network needs a multicast route (see README, 'LCM and multicast')");
}

LcmPublisher::~LcmPublisher() = default;

// The bus stamps its own time: utime is for logs.
void LcmPublisher::publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size, std::int64_t) {
  lcm_->publish(channel, data, static_cast<unsigned int>(size));
}

}  // namespace noisemon::daemon
