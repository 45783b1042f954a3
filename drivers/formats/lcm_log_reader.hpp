// A tolerant reader of LCM log files (the lcm-logger format: per event a big-endian sync word 0xEDA1DA01,
// int64 event number, int64 timestamp, int32 channel length, int32 data length, channel, data).
//
// lcm::LogFile stops at the first damaged header (and allocates whatever length a damaged header claims).
// This reader instead checks each event's framing (channel length 1..999 of printable characters, data inside
// the file, no sync word inside the data unless the next event starts right after it) and, on damage, skips to the next
// sync word and counts the damaged stretch, so one bad event in a long log costs only that event. A log cut
// short ends with a truncated event, counted the same way. It reads a memory-mapped file or any byte buffer
// (the fuzzers use the latter). Payloads are handed out as views into the buffer, without copying.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

namespace noisemon::drivers::formats {

struct LcmLogEvent {
  std::int64_t eventnum = 0;
  std::int64_t timestamp = 0;  // utime the logger gave the event
  std::string_view channel;
  const std::uint8_t* data = nullptr;
  std::int32_t datalen = 0;
  std::size_t offset = 0;  // byte offset of the event's sync word in the log
};

class LcmLogReader {
 public:
  // Maps the file; throws std::runtime_error naming it when it cannot be opened.
  explicit LcmLogReader(const std::filesystem::path& file);
  // Reads a caller-owned buffer (must outlive the reader).
  LcmLogReader(const std::uint8_t* data, std::size_t size);
  ~LcmLogReader();
  LcmLogReader(const LcmLogReader&) = delete;
  LcmLogReader& operator=(const LcmLogReader&) = delete;

  // The next well-framed event; false at the end of the log. The views stay valid while the reader lives.
  bool next(LcmLogEvent& event);

  std::size_t position() const { return pos_; }  // bytes consumed so far
  std::size_t size() const { return size_; }
  // Stretches of bytes that were not a well-framed event (damaged headers, garbage, a truncated last event).
  std::int64_t damaged() const { return damaged_; }
  std::uint64_t damaged_bytes() const { return damaged_bytes_; }
  bool truncated() const { return truncated_; }  // the log ends inside an event
  // Offset of the first damaged stretch (for messages); meaningful when damaged() > 0.
  std::size_t first_damage_offset() const { return first_damage_; }

 private:
  void note_damage(std::size_t from, std::size_t to);

  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
  void* map_ = nullptr;  // when the reader mapped a file
  std::size_t pos_ = 0;
  std::int64_t damaged_ = 0;
  std::uint64_t damaged_bytes_ = 0;
  bool truncated_ = false;
  std::size_t first_damage_ = 0;
};

}  // namespace noisemon::drivers::formats
