// Parser for can-utils `candump -l` log lines: `(1700000000.123456) can0 123#DEADBEEF`, used to replay a
// recorded bus through the same signal map as the live socketcan source.
#pragma once

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>
#include <string_view>

#include "drivers/formats/can_signal_map.hpp"

namespace noisemon::drivers::formats {

struct CandumpRecord {
  std::int64_t utime = 0;  // microseconds since the Unix epoch
  std::string interface;
  CanFrame frame;  // for a remote frame: dlc as requested, data zero
  bool remote = false;
};

// Parses one line (without newline; a trailing '\r' is tolerated). Classic CAN only: 3 hex digits are an
// 11-bit id, 8 hex digits a 29-bit id; data is 0..8 bytes as hex pairs (optionally '.'-separated); `R`
// (optionally followed by a dlc digit) is a remote frame; CAN FD (`##`) and len8_dlc (`_`) are rejected.
// Returns false and sets error ("line N: expected ...") on a bad line.
bool parse_candump_line(std::string_view line, std::size_t line_number, CandumpRecord& out, std::string& error);

// Reads a candump log file record by record; bad lines are skipped and counted, blank lines ignored.
class CandumpReader {
 public:
  explicit CandumpReader(const std::string& path);  // throws std::runtime_error naming the path

  // Next good record; false at end of file.
  bool next(CandumpRecord& out);

  std::size_t bad_lines() const { return bad_lines_; }
  const std::string& last_error() const { return last_error_; }  // of the most recent bad line

 private:
  std::ifstream in_;
  std::string line_;
  std::size_t line_number_ = 0;
  std::size_t bad_lines_ = 0;
  std::string last_error_;
};

}  // namespace noisemon::drivers::formats
