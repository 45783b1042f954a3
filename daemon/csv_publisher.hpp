// The CSV publisher: one row per cycle report, the columns of `noisemon watch --csv` (report_messages.hpp), the
// last naming the run. `noisemon replay --csv` writes its reports with it; other messages are not kept.
#pragma once

#include <fstream>
#include <string>

#include "daemon/publisher.hpp"

namespace noisemon::daemon {

class CsvPublisher final : public Publisher {
 public:
  // Creates (replaces) the file and writes the header; throws std::runtime_error naming it when it cannot.
  explicit CsvPublisher(const std::string& path);

  // The following rows name this run. Not while a pipeline publishes.
  void begin_run(const std::string& condition) override { condition_ = condition; }

  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override;
  void flush() override;

 private:
  std::string path_;
  std::ofstream csv_;
  std::string condition_;
};

}  // namespace noisemon::daemon
