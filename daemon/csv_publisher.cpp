#include "daemon/csv_publisher.hpp"

#include <stdexcept>

#include "daemon/report_messages.hpp"

namespace noisemon::daemon {

CsvPublisher::CsvPublisher(const std::string& path) : path_(path), csv_(path) {
  if (!csv_) throw std::runtime_error(path + ": cannot write CSV file");
  csv_ << cycle_csv_header();
}

void CsvPublisher::publish(const std::string&, const noisemon::cycle_report_t& m, std::int64_t) {
  csv_ << cycle_csv_row(m, condition_);
}

void CsvPublisher::flush() {
  if (!csv_.flush()) throw std::runtime_error(path_ + ": cannot write CSV file (disk full?)");
}

}  // namespace noisemon::daemon
