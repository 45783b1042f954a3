#include "daemon/record_files.hpp"

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

namespace noisemon::daemon {
namespace {

// An event's bytes in an LCM log: sync word, event number, stamp, the two lengths, then channel and data.
constexpr std::uint64_t kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;

}  // namespace

bool valid_test_point(std::string_view name) {
  return !name.empty() && name.front() != '.' && std::all_of(name.begin(), name.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || ch == '.' || ch == '_' || ch == '-';
  });
}

std::string record_file_name(const std::string& cell, const std::string& test_point, std::time_t start, int part) {
  std::tm local{};
  localtime_r(&start, &local);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%d-%H%M%S", &local);
  char number[16];
  std::snprintf(number, sizeof number, "%03d", part);
  return (cell.empty() ? "" : cell + "_") + test_point + "_" + stamp + "_" + number + ".lcmlog";
}

RecordFiles::RecordFiles(RecordFilesOptions options) : options_(std::move(options)) {
  if (options_.next_path) open_next();
}

void RecordFiles::begin(std::function<std::filesystem::path(int opened)> next_path) {
  close();
  options_.next_path = std::move(next_path);
  recording_parts_ = 0;
  open_next();
}

RecordFiles::~RecordFiles() {
  try {
    close();
  } catch (const std::exception&) {  // the writer has reported the error that failed it already
  }
}

void RecordFiles::fail(const char* what, int error) const {
  throw std::runtime_error(path_.string() + ": " + what + " (" + std::strerror(error) + ")");
}

void RecordFiles::open_next() {
  close();
  if (!options_.next_path) throw std::logic_error("RecordFiles: a recording's part without begin()");
  path_ = options_.next_path(recording_parts_);
  errno = 0;
  log_ = std::make_unique<lcm::LogFile>(path_.string(), "w");
  if (!log_->good()) {
    const int error = errno != 0 ? errno : EIO;
    log_.reset();
    fail("cannot create the recording's file", error);
  }
  ++parts_;
  ++recording_parts_;
  bytes_in_part_ = 0;
  events_in_part_ = 0;
  opened_ = synced_ = Clock::now();
  for (const Lead& lead : leads_) append(lead.channel, lead.data.data(), lead.data.size(), lead.utime);
}

void RecordFiles::append(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime) {
  // lcm::LogEvent holds a mutable pointer and a string; writeEvent only reads them.
  lcm::LogEvent e{0, utime, std::string(channel), static_cast<std::int32_t>(size), const_cast<std::uint8_t*>(data)};
  errno = 0;
  if (log_->writeEvent(&e) != 0) fail("cannot write", errno != 0 ? errno : EIO);
  bytes_in_part_ += kEventHeaderBytes + channel.size() + size;
  bytes_written_ += kEventHeaderBytes + channel.size() + size;
}

void RecordFiles::remember_lead(std::string_view channel, const std::uint8_t* data, std::size_t size,
                                std::int64_t utime) {
  if (std::find(options_.lead_channels.begin(), options_.lead_channels.end(), channel) == options_.lead_channels.end())
    return;
  auto lead = std::find_if(leads_.begin(), leads_.end(), [&](const Lead& l) { return l.channel == channel; });
  if (lead == leads_.end()) lead = leads_.insert(leads_.end(), Lead{std::string(channel), {}, 0});
  lead->data.assign(data, data + size);
  lead->utime = utime;
}

void RecordFiles::write(std::string_view channel, const std::uint8_t* data, std::size_t size, std::int64_t utime) {
  if (!log_) open_next();  // after close()
  // A part holds at least one event of its own beside its leads, however small rotate_bytes.
  const std::uint64_t event_bytes = kEventHeaderBytes + channel.size() + size;
  const bool full = options_.rotate_bytes > 0 && bytes_in_part_ + event_bytes > options_.rotate_bytes;
  const bool old =
      options_.rotate_s > 0 && std::chrono::duration<double>(Clock::now() - opened_).count() >= options_.rotate_s;
  if (events_in_part_ > 0 && (full || old)) open_next();
  append(channel, data, size, utime);
  ++events_in_part_;
  remember_lead(channel, data, size, utime);
}

void RecordFiles::flush() {
  if (!log_) return;
  if (std::fflush(log_->getFilePtr()) != 0) fail("cannot write", errno);
  const auto now = Clock::now();
  if (options_.fsync == RecordFsync::kInterval &&
      std::chrono::duration<double>(now - synced_).count() >= options_.fsync_interval_s) {
    if (::fsync(::fileno(log_->getFilePtr())) != 0 && errno != EINVAL) fail("cannot sync", errno);
    synced_ = now;
  }
}

void RecordFiles::close() {
  if (!log_) return;
  std::unique_ptr<lcm::LogFile> log = std::move(log_);  // closed on the way out, whatever fails
  if (std::fflush(log->getFilePtr()) != 0) fail("cannot write", errno);
  // EINVAL: a file that cannot be synced (a pipe, a device): nothing to make durable.
  if (options_.fsync != RecordFsync::kNone && ::fsync(::fileno(log->getFilePtr())) != 0 && errno != EINVAL)
    fail("cannot sync", errno);
}

}  // namespace noisemon::daemon
