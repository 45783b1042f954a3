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
void LcmPublisher::publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t) {
  lcm_->publish(channel, &m);
}
void LcmPublisher::publish(const std::string& channel, const noisemon::status_t& m, std::int64_t) {
  lcm_->publish(channel, &m);
}
void LcmPublisher::publish(const std::string& channel, const noisemon::session_t& m, std::int64_t) {
  lcm_->publish(channel, &m);
}
void LcmPublisher::publish(const std::string& channel, const noisemon::raw_block_t& m, std::int64_t) {
  lcm_->publish(channel, &m);
}
void LcmPublisher::publish(const std::string& channel, const noisemon::operating_point_t& m, std::int64_t) {
  lcm_->publish(channel, &m);
}
void LcmPublisher::publish(const std::string& channel, const noisemon::cycle_stats_t& m, std::int64_t) {
  lcm_->publish(channel, &m);
}

}  // namespace noisemon::daemon
