#include "daemon/csv_publisher.hpp"

#include <stdexcept>

#include "daemon/report_messages.hpp"

namespace noisemon::daemon {

CsvPublisher::CsvPublisher(const std::string& path) : path_(path), csv_(path) {
  if (!csv_) throw std::runtime_error(path + ": cannot write CSV file");
  csv_ << cycle_csv_header();
}

void CsvPublisher::publish_bytes(const std::string&, const std::uint8_t* data, std::size_t size, std::int64_t) {
  if (const auto report = decode_as<noisemon::cycle_report_t>(data, size)) csv_ << cycle_csv_row(*report, condition_);
}

void CsvPublisher::flush() {
  if (!csv_.flush()) throw std::runtime_error(path_ + ": cannot write CSV file (disk full?)");
}

}  // namespace noisemon::daemon
