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

  void publish(const std::string& channel, const noisemon::cycle_report_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::status_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::session_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::raw_block_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::operating_point_t& m, std::int64_t utime) override;
  void publish(const std::string& channel, const noisemon::cycle_stats_t& m, std::int64_t utime) override;

 private:
  std::unique_ptr<lcm::LCM> lcm_;
};

}  // namespace noisemon::daemon
