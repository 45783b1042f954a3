#include "daemon/recorder.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <system_error>
#include <thread>

#include "daemon/record_files.hpp"
#include "drivers/source.hpp"
#include "noisemon/record_loss_t.hpp"

namespace noisemon::daemon {
namespace {

constexpr auto kWriterIdle = std::chrono::milliseconds(100);  // the writer's longest sleep with nothing queued
constexpr auto kProducerPoll = std::chrono::microseconds(200);
constexpr int kWriterBatch = 256;  // events between two flushes while the queue stays full

std::size_t bytes_of_mb(double mb) { return static_cast<std::size_t>(std::llround(mb * 1024 * 1024)); }

void make_folder(const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("[record] dir " + dir + ": cannot make the folder (" + ec.message() + ")");
}

// [record] dir with record_file_name's names from the recording's start (now); a name that exists is skipped, never
// overwritten.
Recorder::NextPath files_in_folder(const std::string& dir, const std::string& cell, const std::string& test_point) {
  make_folder(dir);
  return [dir = std::filesystem::path(dir), cell, test_point, start = std::time(nullptr)](int opened) {
    for (int part = opened + 1;; ++part) {
      std::filesystem::path p = dir / record_file_name(cell, test_point, start, part);
      if (!std::filesystem::exists(p)) return p;
    }
  };
}

RecordFilesOptions files_options(const RecordConfig& record, const std::vector<std::string>& lead_channels) {
  RecordFilesOptions o;
  o.rotate_bytes = bytes_of_mb(record.rotate_mb);
  o.rotate_s = record.rotate_s;
  o.fsync = record.fsync;
  o.fsync_interval_s = record.fsync_interval_s;
  o.lead_channels = lead_channels;
  return o;
}

}  // namespace

Recorder::Recorder(const RecordConfig& record, const LcmConfig& lcm, const drivers::ThreadPolicy& policy,
                   NextPath next_path)
    : record_(record),
      cell_(lcm.cell),
      loss_channel_(lcm.record_loss_channel),
      ack_channel_(lcm.command_ack_channel),
      // What a reader of a part needs before its raw blocks: the session, and the operating point in force.
      lead_channels_{lcm.session_channel, lcm.operating_point_channel},
      next_path_(std::move(next_path)),
      queue_(std::max<std::size_t>(bytes_of_mb(record.buffer_mb), 1)),
      files_(std::make_unique<RecordFiles>(files_options(record, lead_channels_))) {
  if (record.autostart) {
    open_recording(record.test_point);
    recording_ = true;
  } else if (!next_path_) {
    make_folder(record.dir);
  }
  writer_.start("nm-record", policy, [this](const std::atomic<bool>& stop) { run_writer(stop); });
  spdlog::info("{} ({:.3g} MiB buffer)", recording_ ? "recording into " + file_ : "recorder waiting for a command",
               static_cast<double>(queue_.capacity_bytes()) / (1 << 20));
}

Recorder::~Recorder() { stop(); }

// The writer's (or the constructor's, before the writer starts): a new recording's first part.
void Recorder::open_recording(const std::string& test_point) {
  if (next_path_)
    files_->begin([hook = next_path_, before = files_->parts()](int opened) { return hook(before + opened); });
  else
    files_->begin(files_in_folder(record_.dir, cell_, test_point));
  std::lock_guard lock(mutex_);
  file_ = files_->path().string();
  parts_.store(files_->parts(), std::memory_order_relaxed);
}

void Recorder::close_recording() {
  files_->close();
  std::lock_guard lock(mutex_);
  file_.clear();
}

void Recorder::request(RecorderRequest command) {
  const auto refuse = [&](const std::string& why) { acknowledge(command, drivers::wall_utime(), false, why, ""); };
  if (command.verb == CommandVerb::kRecordStart && !valid_test_point(command.test_point))
    return refuse("test point '" + command.test_point + "': " + kTestPointRule);
  if (!writer_running()) {
    const std::string error = writer_.status().error;
    return refuse(error.empty() ? "the recorder has stopped" : "the recorder stopped earlier: " + error);
  }
  std::lock_guard lock(commands_mutex_);
  inbox_.push_back(std::move(command));
  inbox_waiting_.store(true, std::memory_order_release);
}

// The producer's: the commands requested go into the queue as control events (an empty channel, which no LCM
// channel is), in order with the messages; a full queue leaves them for the next message.
void Recorder::take_commands(std::int64_t utime) {
  if (!inbox_waiting_.load(std::memory_order_acquire)) return;
  std::lock_guard lock(commands_mutex_);
  while (!inbox_.empty()) {
    // A stop's recording keeps its own losses: their marker goes in before it.
    if (inbox_.front().verb != CommandVerb::kMark && pending_.messages > 0 && !push_marker(utime)) return;
    if (!queue_.push({}, nullptr, 0, utime)) return;
    control_.push_back(std::move(inbox_.front()));
    inbox_.pop_front();
    if (control_.back().verb != CommandVerb::kMark) recording_ = control_.back().verb == CommandVerb::kRecordStart;
  }
  inbox_waiting_.store(false, std::memory_order_release);
  wakeup_.notify();
}

void Recorder::acknowledge(const RecorderRequest& c, std::int64_t utime, bool ok, const std::string& message,
                           const std::string& file) {
  noisemon::command_ack_t ack;
  ack.utime = utime;
  ack.id = c.id;
  ack.verb = std::string(command_verb_name(c.verb));
  ack.test_point = c.test_point;
  ack.text = c.text;
  ack.ok = ok;
  ack.message = message;
  ack.file = file;
  if (ok && files_->is_open()) write_ack(ack);
  std::lock_guard lock(sink_mutex_);
  if (ack_sink_) ack_sink_(ack);
}

void Recorder::write_ack(const noisemon::command_ack_t& ack) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(ack.getEncodedSize()));
  ack.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  files_->write(ack_channel_, bytes.data(), bytes.size(), ack.utime);
}

// The writer's: the next control event's command, where it sits among the messages.
void Recorder::carry_out(std::int64_t utime) {
  RecorderRequest c;
  {
    std::lock_guard lock(commands_mutex_);
    c = std::move(control_.front());
    control_.pop_front();
  }
  try {
    if (c.verb == CommandVerb::kRecordStart) {
      close_recording();
      open_recording(c.test_point);
      spdlog::info("recording test point {} into {}", c.test_point, files_->path().string());
      acknowledge(c, utime, true, "recording test point " + c.test_point, files_->path().string());
    } else if (c.verb == CommandVerb::kRecordStop && files_->is_open()) {
      const std::string file = files_->path().string();
      acknowledge(c, utime, true, "recording stopped: " + file, file);
      close_recording();
      spdlog::info("recording stopped by command: {}", file);
    } else if (c.verb == CommandVerb::kRecordStop) {
      acknowledge(c, utime, true, "no recording was running", "");
    } else {
      const std::string file = files_->is_open() ? files_->path().string() : "";
      acknowledge(c, utime, true, file.empty() ? "marked; no recording is running" : "marked in " + file, file);
    }
  } catch (const std::exception& ex) {
    acknowledge(c, utime, false, ex.what(), "");
    throw;
  }
}

void Recorder::count_loss(const std::string& channel, std::size_t size, std::int64_t utime) {
  if (pending_.messages == 0) pending_.first_utime = utime;
  ++pending_.messages;
  pending_.bytes += static_cast<std::int64_t>(size);
  pending_.last_utime = utime;
  auto it = std::find_if(pending_.by_channel.begin(), pending_.by_channel.end(),
                         [&](const auto& c) { return c.first == channel; });
  if (it == pending_.by_channel.end()) it = pending_.by_channel.insert(it, {channel, 0});
  ++it->second;
  lost_.fetch_add(1, std::memory_order_relaxed);
  bytes_lost_.fetch_add(static_cast<std::int64_t>(size), std::memory_order_relaxed);
  std::lock_guard lock(mutex_);
  auto total =
      std::find_if(lost_by_channel_.begin(), lost_by_channel_.end(), [&](const auto& c) { return c.first == channel; });
  if (total == lost_by_channel_.end()) total = lost_by_channel_.insert(total, {channel, 0});
  ++total->second;
}

// The losses not yet in the file, as a marker queued ahead of the next message; false when it does not fit either.
bool Recorder::push_marker(std::int64_t utime) {
  noisemon::record_loss_t m;
  m.utime = utime;
  m.first_lost_utime = pending_.first_utime;
  m.last_lost_utime = pending_.last_utime;
  m.messages = pending_.messages;
  m.bytes = pending_.bytes;
  m.nchannels = static_cast<std::int16_t>(pending_.by_channel.size());
  for (const auto& [channel, n] : pending_.by_channel) {
    m.channel.push_back(channel);
    m.channel_messages.push_back(n);
  }
  marker_bytes_.resize(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(marker_bytes_.data(), 0, static_cast<int>(marker_bytes_.size()));
  if (!queue_.push(loss_channel_, marker_bytes_.data(), marker_bytes_.size(), utime)) return false;
  pending_.messages = pending_.bytes = 0;
  pending_.by_channel.clear();
  wakeup_.notify();
  return true;
}

void Recorder::publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                             std::int64_t utime) {
  if (!writer_running()) return;  // stopped, or failed: the error is in the state
  take_commands(utime);
  if (!recording_) {
    // Between recordings only the leads go to the writer, to start the next recording with; none is counted.
    if (std::find(lead_channels_.begin(), lead_channels_.end(), channel) != lead_channels_.end() &&
        queue_.push(channel, data, size, utime))
      wakeup_.notify();
    return;
  }
  sent_.fetch_add(1, std::memory_order_relaxed);
  // The marker goes first, so it sits where the loss was: when it does not fit, neither does this message.
  if ((pending_.messages > 0 && !push_marker(utime)) || !queue_.push(channel, data, size, utime)) {
    count_loss(channel, size, utime);
    return;
  }
  wakeup_.notify();
}

void Recorder::wait_for_room_and_mark() {
  while (pending_.messages > 0 && writer_running() && !push_marker(pending_.last_utime)) {
    wakeup_.notify();
    std::this_thread::sleep_for(kProducerPoll);
  }
}

void Recorder::flush() {
  wait_for_room_and_mark();
  const std::uint64_t ask = flush_asked_.fetch_add(1, std::memory_order_acq_rel) + 1;
  wakeup_.notify();
  while (writer_running() && flush_done_.load(std::memory_order_acquire) < ask)
    std::this_thread::sleep_for(kProducerPoll);
}

void Recorder::stop() {
  if (!writer_.joinable()) return;
  wait_for_room_and_mark();  // the publishing thread has ended: this thread is the producer now
  writer_.request_stop();
  wakeup_.notify();
  writer_.join();
  std::deque<RecorderRequest> left;
  {
    std::lock_guard lock(commands_mutex_);
    left.swap(control_);
    for (RecorderRequest& c : inbox_) left.push_back(std::move(c));
    inbox_.clear();
  }
  for (const RecorderRequest& c : left)
    acknowledge(c, drivers::wall_utime(), false, "the recorder stopped before carrying it out", "");
  const RecorderState s = state();
  if (s.error.empty())
    spdlog::info("recording stopped: {} messages in {} file(s), {} lost", s.messages_written, s.files, s.messages_lost);
}

void Recorder::write_event(const QueuedEvent& e) {
  if (e.channel.empty()) return carry_out(e.utime);
  if (!files_->is_open()) return files_->keep_lead(e.channel, e.data.data(), e.data.size(), e.utime);
  files_->write(e.channel, e.data.data(), e.data.size(), e.utime);
  if (e.channel != loss_channel_) written_.fetch_add(1, std::memory_order_relaxed);
  bytes_written_.store(static_cast<std::int64_t>(files_->bytes_written()), std::memory_order_relaxed);
  if (files_->parts() != parts_.load(std::memory_order_relaxed)) {
    std::lock_guard lock(mutex_);
    file_ = files_->path().string();
    parts_.store(files_->parts(), std::memory_order_relaxed);
    spdlog::info("recording into {}", file_);
  }
}

void Recorder::run_writer(const std::atomic<bool>& stop) {
  QueuedEvent e;
  try {
    while (true) {
      // Read before draining: everything published before the ask or the stop is in the queue by now.
      const std::uint64_t asked = flush_asked_.load(std::memory_order_acquire);
      const bool stopping = stop.load(std::memory_order_acquire);
      int taken = 0;
      while (taken < kWriterBatch && queue_.pop(e)) {
        write_event(e);
        ++taken;
      }
      files_->flush();  // a process killed now leaves every whole event on disk; the fsync interval is kept
      if (taken == kWriterBatch) continue;  // more may wait: on with them
      flush_done_.store(asked, std::memory_order_release);
      if (stopping) break;
      wakeup_.wait_for(kWriterIdle);
    }
    close_recording();
  } catch (const std::exception& ex) {
    spdlog::error("recording stopped: {}; the daemon goes on without it", ex.what());
    throw;
  }
}

RecorderState Recorder::state() const {
  RecorderState s;
  const drivers::DriverThreadStatus t = writer_.status();
  s.recording = t.state == drivers::ThreadState::kRunning;  // and a file open: below
  s.error = t.error;
  s.files = parts_.load(std::memory_order_relaxed);
  s.messages_sent = sent_.load(std::memory_order_relaxed);
  s.messages_written = written_.load(std::memory_order_relaxed);
  s.messages_lost = lost_.load(std::memory_order_relaxed);
  s.bytes_written = bytes_written_.load(std::memory_order_relaxed);
  s.bytes_lost = bytes_lost_.load(std::memory_order_relaxed);
  std::lock_guard lock(mutex_);
  s.recording = s.recording && !file_.empty();
  if (s.recording) s.file = file_;
  s.lost_by_channel = lost_by_channel_;
  return s;
}

void Recorder::add_status(noisemon::status_t& status) const {
  const RecorderState s = state();
  const drivers::DriverThreadStatus t = writer_.status();
  status.thread_name.push_back(t.name);
  status.thread_state.push_back(static_cast<std::int8_t>(t.state));
  status.thread_error.push_back(t.error);
  // Its buffer is a ring like the pipeline's: how full, and the messages it could not take.
  status.ring_name.push_back("record");
  status.ring_fill.push_back(static_cast<float>(queue_.fill_fraction()));
  status.ring_overruns.push_back(s.messages_lost);
  const std::pair<std::string, std::int64_t> counts[] = {{"record.files", s.files},
                                                         {"record.messages_sent", s.messages_sent},
                                                         {"record.messages_written", s.messages_written},
                                                         {"record.bytes_written", s.bytes_written},
                                                         {"record.bytes_lost", s.bytes_lost}};
  for (const auto& [name, value] : counts) {
    status.counter_name.push_back(name);
    status.counter_value.push_back(value);
    status.counter_is_gauge.push_back(false);
  }
  for (const auto& [channel, n] : s.lost_by_channel) {
    status.counter_name.push_back("record.lost." + channel);
    status.counter_value.push_back(n);
    status.counter_is_gauge.push_back(false);
  }
  status.record_file = s.file;
}

}  // namespace noisemon::daemon
