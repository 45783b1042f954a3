// The files of one recording (the recorder's writer thread writes through it): LCM log files in the lcm-logger
// format (lcm::LogFile, as log_publisher.hpp), a new part once a file holds rotate_mb or is rotate_s old, made
// durable as [record] fsync says. Each part starts with the latest event of the channels a reader needs first (the
// session, the operating point), so every part replays on its own; they are kept between recordings too (keep_lead),
// so a recording started by command begins with them.
//
// Names: <cell>_<test_point>_<YYYYmmdd-HHMMSS>_<NNN>.lcmlog in the recording's folder (without "<cell>_" when the
// cell is unnamed), the recording's start in local time and the part number from 001; a name that exists (a
// recording started in the same second) is never overwritten: its number is skipped.
#pragma once

#include <chrono>
#include <cstdint>
#include <ctime>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "daemon/config.hpp"

namespace lcm {
class LogFile;
}

namespace noisemon::daemon {

// A test point's name is part of the file names: letters, digits, '.', '_' or '-', not starting with '.'.
inline constexpr const char* kTestPointRule =
    "expected letters, digits, '.', '_' or '-', not starting with '.' (a part of file names)";
[[nodiscard]] bool valid_test_point(std::string_view name);

// The name of part `part` (1, 2, ...) of a recording started at `start`.
[[nodiscard]] std::string record_file_name(const std::string& cell, const std::string& test_point, std::time_t start,
                                           int part);

struct RecordFilesOptions {
  std::uint64_t rotate_bytes = 1ull << 30;  // 0: never by size
  double rotate_s = 0;                      // 0: never by age
  RecordFsync fsync = RecordFsync::kRotate;
  double fsync_interval_s = 10;
  std::vector<std::string> lead_channels;  // their latest event starts every part after the first
  // Where the next part goes, given the number of parts of this recording opened so far (tests: a device, a pipe).
  // Empty: no recording until begin().
  std::function<std::filesystem::path(int opened)> next_path;
};

class RecordFiles {
 public:
  // Opens the first part when options.next_path is given: throws std::runtime_error naming the file and the
  // system's reason when it cannot.
  explicit RecordFiles(RecordFilesOptions options);
  ~RecordFiles();  // close(), errors ignored
  RecordFiles(const RecordFiles&) = delete;
  RecordFiles& operator=(const RecordFiles&) = delete;

  // One event, in a new part first when this one is full or old. Throws std::runtime_error naming the file and
  // the system's reason (ENOSPC, EIO, ...) when it cannot be written; the file then ends with a partial event at
  // most, which readers skip.
  void write(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime);
  // Hands what is buffered to the kernel (so a killed process leaves it on disk), and fsyncs when the interval
  // policy is due. Throws as write().
  void flush();
  // Flushes, fsyncs (fsync "rotate" or "interval") and closes the part. Throws as write().
  void close();
  // Closes the recording's part, and opens the first part of a new recording whose parts go where next_path says.
  // Throws as the constructor.
  void begin(std::function<std::filesystem::path(int opened)> next_path);
  // Between recordings: the event is not written, but a lead channel's is kept to start the next part with.
  void keep_lead(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime) {
    remember_lead(channel, data, size, utime);
  }
  [[nodiscard]] bool is_open() const { return log_ != nullptr; }

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }  // the part written now
  [[nodiscard]] int parts() const { return parts_; }                         // every recording's
  [[nodiscard]] std::uint64_t bytes_in_part() const { return bytes_in_part_; }
  [[nodiscard]] std::uint64_t bytes_written() const { return bytes_written_; }  // every part's

 private:
  using Clock = std::chrono::steady_clock;
  void open_next();
  void append(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime);
  [[noreturn]] void fail(const char* what, int error) const;
  void remember_lead(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime);

  struct Lead {
    std::string channel;
    std::vector<std::uint8_t> data;
    std::int64_t utime = 0;
  };
  RecordFilesOptions options_;
  std::unique_ptr<lcm::LogFile> log_;
  std::filesystem::path path_;
  int parts_ = 0, recording_parts_ = 0;
  std::uint64_t bytes_in_part_ = 0, bytes_written_ = 0;
  std::int64_t events_in_part_ = 0;  // beside its leads
  Clock::time_point opened_, synced_;
  std::vector<Lead> leads_;
};

}  // namespace noisemon::daemon
