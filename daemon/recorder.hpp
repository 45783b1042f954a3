// The recorder inside the daemon ([record]): a Publisher that copies every message the pipeline publishes into a
// bounded buffer (event_queue.hpp) and a writer thread ("nm-record") that drains it into LCM log files
// (record_files.hpp), never through a socket. publish_bytes never blocks the publishing thread: when the buffer is
// full the message is dropped and counted, per channel, and a loss marker (record_loss_t on
// [lcm] record_loss_channel) goes into the file where the loss happened. A file that cannot be written (disk full,
// I/O error) stops the recording with the error kept in its state and in the daemon's status; the pipeline goes on.
//
// Recordings start with the daemon ([record] autostart) or by command (request: `noisemon record`, the dashboard,
// through command_listener.hpp): a command goes into the buffer as a control event between the messages, so it
// takes effect exactly there; the writer carries it out (a new recording of a test point, the end of one, a mark)
// and acknowledges it (command_ack_t) to the sink and, when a file is open, into the file itself.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/event_queue.hpp"
#include "daemon/publisher.hpp"
#include "daemon/record_command.hpp"
#include "daemon/wakeup.hpp"
#include "drivers/worker_thread.hpp"
#include "noisemon/command_ack_t.hpp"

namespace noisemon::daemon {

class RecordFiles;

struct RecorderState {
  bool recording = false;             // the writer runs and a file is open
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

  using AckSink = std::function<void(const noisemon::command_ack_t&)>;

  // Makes the folder and (autostart) the first file, and starts the writer. Throws std::runtime_error naming the
  // folder or file (and the system's reason) when it cannot: an unwritable folder is an error at start, not later.
  // next_path (tests): where part n of any recording goes, n counted over all of them.
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

  // Where the acknowledgements go (called from the writer thread, or request's); empty: nowhere. Once this returns,
  // the previous sink is not being called and will not be.
  void set_ack_sink(AckSink sink) {
    std::lock_guard lock(sink_mutex_);
    ack_sink_ = std::move(sink);
  }
  // Any thread: carried out between the messages at the next one the publishing thread hands over, then
  // acknowledged. Refused at once (acknowledged, not ok) when the recorder has failed or a test point is no name.
  void request(RecorderRequest command);

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
  void take_commands(std::int64_t utime);
  void carry_out(std::int64_t utime);
  void open_recording(const std::string& test_point);
  void close_recording();
  void write_ack(const noisemon::command_ack_t& ack);
  void acknowledge(const RecorderRequest& c, std::int64_t utime, bool ok, const std::string& message,
                   const std::string& file);
  [[nodiscard]] bool push_marker(std::int64_t utime);
  void run_writer(const std::atomic<bool>& stop);
  void write_event(const QueuedEvent& e);
  void wait_for_room_and_mark();
  [[nodiscard]] bool writer_running() const { return writer_.state() == drivers::ThreadState::kRunning; }

  const RecordConfig record_;
  const std::string cell_, loss_channel_, ack_channel_;
  const std::vector<std::string> lead_channels_;
  const NextPath next_path_;  // tests'; empty: [record] dir
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
  // Commands: requested (inbox_), then taken by the producer into the queue as control events (control_, in their
  // order there) for the writer. The producer's own: whether messages go into the queue (a recording is on).
  std::mutex commands_mutex_;
  std::deque<RecorderRequest> inbox_, control_;
  std::atomic<bool> inbox_waiting_{false};
  bool recording_ = false;
  std::mutex sink_mutex_;  // held while the sink is called
  AckSink ack_sink_;
  std::unique_ptr<RecordFiles> files_;      // the writer's once it runs; closed between recordings
  drivers::WorkerThread writer_{"record"};  // last: stopped first
};

}  // namespace noisemon::daemon
