// The recorder inside the daemon ([record]): a Publisher that copies every message the pipeline publishes into a
// bounded buffer (event_queue.hpp) and a writer thread ("nm-record") that drains it into LCM log files
// (record_files.hpp), never through a socket. publish_bytes never blocks the publishing thread: when the buffer is
// full the message is dropped and counted, per channel, and a loss marker (record_loss_t on
// [lcm] record_loss_channel) goes into the file where the loss happened. A file that cannot be written (disk full,
// I/O error) stops the recording with the error kept in its state and in the daemon's status; the pipeline goes on.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/event_queue.hpp"
#include "daemon/publisher.hpp"
#include "daemon/wakeup.hpp"
#include "drivers/worker_thread.hpp"

namespace noisemon::daemon {

class RecordFiles;

struct RecorderState {
  bool recording = false;             // the writer runs
  std::string file;                   // the part written now ("" once stopped)
  std::string error;                  // why the recording stopped, when it failed
  int files = 0;                      // parts opened
  std::int64_t messages_sent = 0;     // handed to publish_bytes while recording
  std::int64_t messages_written = 0;  // of those, in the files (loss markers and each part's leads not counted)
  std::int64_t messages_lost = 0;     // of those, dropped on a full buffer
  std::int64_t bytes_written = 0;     // every byte of the files, markers and leads too
  std::int64_t bytes_lost = 0;
  std::vector<std::pair<std::string, std::int64_t>> lost_by_channel;  // messages lost, per channel
};

class Recorder final : public Publisher {
 public:
  // Where part n goes given the number of parts opened so far; empty: [record] dir with record_file_name's names.
  using NextPath = std::function<std::filesystem::path(int opened)>;

  // Makes the folder and the first file and starts the writer. Throws std::runtime_error naming the folder or
  // file (and the system's reason) when it cannot: an unwritable folder is an error at start, not later.
  Recorder(const RecordConfig& record, const LcmConfig& lcm, const drivers::ThreadPolicy& policy = {},
           NextPath next_path = {});
  ~Recorder() override;  // stop()

  // The publishing thread's (one thread at a time): copies the message into the buffer, or counts it lost.
  void publish_bytes(const std::string& channel, const std::uint8_t* data, std::size_t size,
                     std::int64_t utime) override;
  // The publishing thread's: waits until everything published so far (and the last loss marker) is in the file and
  // handed to the kernel, or the writer has stopped.
  void flush() override;
  void add_status(noisemon::status_t& status) const override;

  // Writes out what is queued, closes the file (fsync as configured) and joins the writer. Idempotent.
  void stop();
  // Any thread.
  [[nodiscard]] RecorderState state() const;

 private:
  struct Loss {
    std::int64_t messages = 0, bytes = 0, first_utime = 0, last_utime = 0;
    std::vector<std::pair<std::string, std::int64_t>> by_channel;
  };
  void count_loss(const std::string& channel, std::size_t size, std::int64_t utime);
  [[nodiscard]] bool push_marker(std::int64_t utime);
  void run_writer(const std::atomic<bool>& stop);
  void write_event(const QueuedEvent& e);
  void wait_for_room_and_mark();
  [[nodiscard]] bool writer_running() const { return writer_.state() == drivers::ThreadState::kRunning; }

  const std::string loss_channel_;
  EventQueue queue_;
  Wakeup wakeup_;  // an event is queued, or a flush is asked for
  // The producer's: losses not yet marked in the file, and a reused encoding of the marker.
  Loss pending_;
  std::vector<std::uint8_t> marker_bytes_;
  std::atomic<std::uint64_t> flush_asked_{0}, flush_done_{0};
  std::atomic<std::int64_t> sent_{0}, written_{0}, lost_{0}, bytes_written_{0}, bytes_lost_{0};
  std::atomic<int> parts_{0};
  mutable std::mutex mutex_;  // guards file_ and lost_by_channel_ (written on a new part and on a loss only)
  std::string file_;
  std::vector<std::pair<std::string, std::int64_t>> lost_by_channel_;
  std::unique_ptr<RecordFiles> files_;      // the writer's once it runs
  drivers::WorkerThread writer_{"record"};  // last: stopped first
};

}  // namespace noisemon::daemon
