#include "drivers/formats/lcm_log_reader.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "drivers/formats/big_endian.hpp"

namespace noisemon::drivers::formats {
namespace {

constexpr std::uint8_t kSync[4] = {0xED, 0xA1, 0xDA, 0x01};
constexpr std::size_t kHeaderBytes = 4 + 8 + 8 + 4 + 4;
constexpr std::int32_t kMaxChannelLength = 1000;  // lcm's own limit (eventlog.c)

}  // namespace

LcmLogReader::LcmLogReader(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error(file.string() + ": cannot open log file (" + std::strerror(errno) + ")");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw std::runtime_error(file.string() + ": cannot open log file (not a regular file)");
  }
  size_ = static_cast<std::size_t>(st.st_size);
  if (size_ > 0) {
    map_ = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (map_ == MAP_FAILED) {
      map_ = nullptr;
      ::close(fd);
      throw std::runtime_error(file.string() + ": cannot map log file (" + std::strerror(errno) + ")");
    }
    ::madvise(map_, size_, MADV_SEQUENTIAL);
    data_ = static_cast<const std::uint8_t*>(map_);
  }
  ::close(fd);
}

LcmLogReader::LcmLogReader(const std::uint8_t* data, std::size_t size) : data_(data), size_(data ? size : 0) {}

LcmLogReader::~LcmLogReader() {
  if (map_) ::munmap(map_, size_);
}

void LcmLogReader::note_damage(std::size_t from, std::size_t to) {
  if (to <= from) return;
  if (damaged_ == 0) first_damage_ = from;
  ++damaged_;
  damaged_bytes_ += to - from;
}

bool LcmLogReader::next(LcmLogEvent& e) {
  // Offset of the next sync word at or after `from` (size_ when there is none).
  const auto find_sync = [this](std::size_t from) {
    while (from + 4 <= size_) {
      const void* hit = std::memchr(data_ + from, kSync[0], size_ - from - 3);
      if (!hit) break;
      const auto at = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - data_);
      if (std::memcmp(data_ + at, kSync, 4) == 0) return at;
      from = at + 1;
    }
    return size_;
  };
  while (pos_ < size_) {
    const std::size_t m = find_sync(pos_);
    if (m == size_) {  // bytes that hold no event at all
      truncated_ = true;
      note_damage(pos_, size_);
      pos_ = size_;
      return false;
    }
    note_damage(pos_, m);
    if (size_ - m < kHeaderBytes) {
      truncated_ = true;
      note_damage(m, size_);
      pos_ = size_;
      return false;
    }
    const std::uint8_t* h = data_ + m + 4;
    const auto eventnum = static_cast<std::int64_t>(read_be64(h));
    const auto timestamp = static_cast<std::int64_t>(read_be64(h + 8));
    const auto channel_len = read_be32(h + 16);
    const auto data_len = read_be32(h + 20);
    bool ok = channel_len >= 1 && channel_len < kMaxChannelLength && data_len >= 0;
    const std::uint64_t end = m + kHeaderBytes + static_cast<std::uint64_t>(ok ? channel_len : 0) +
                              static_cast<std::uint64_t>(ok ? data_len : 0);
    if (ok && end > size_) {
      // Either the log was cut inside this event or its length field is damaged: a later sync word tells.
      const std::size_t later = find_sync(m + 4);
      if (later == size_) {
        truncated_ = true;
        note_damage(m, size_);
        pos_ = size_;
        return false;
      }
      ok = false;
    }
    if (ok) {
      const std::uint8_t* ch = data_ + m + kHeaderBytes;
      for (std::int32_t i = 0; i < channel_len && ok; ++i) ok = ch[i] >= 0x20 && ch[i] < 0x7f;
      // The next event should start right after this one. When it does not, either garbage follows (the event is
      // fine: the garbage is skipped on the next call) or this event's length is damaged and it swallowed the
      // start of the next event, whose sync word then lies inside the claimed payload.
      if (ok && size_ - end >= 4 && std::memcmp(data_ + end, kSync, 4) != 0) {
        const std::size_t payload = m + kHeaderBytes + static_cast<std::size_t>(channel_len);
        const std::size_t inside = find_sync(payload);
        ok = inside >= end;
      }
    }
    if (!ok) {
      const std::size_t later = find_sync(m + 1);
      note_damage(m, later);
      pos_ = later;
      continue;
    }
    e.eventnum = eventnum;
    e.timestamp = timestamp;
    e.channel = std::string_view(reinterpret_cast<const char*>(data_ + m + kHeaderBytes),
                                 static_cast<std::size_t>(channel_len));
    e.data = data_ + m + kHeaderBytes + channel_len;
    e.datalen = data_len;
    e.offset = m;
    pos_ = static_cast<std::size_t>(end);
    return true;
  }
  return false;
}

}  // namespace noisemon::drivers::formats
