// The daemon's ear for the test bed: command_t on [lcm] command_channel (record start and stop with a test point,
// mark an event; record_command.hpp), handed to the recorder, and each answered with a command_ack_t on
// [lcm] command_ack_channel. The bus may drop a command or its answer, so a sender repeats it under the same id
// until answered: each id is carried out once, and a repeat gets the answer again.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "daemon/config.hpp"
#include "daemon/recorder.hpp"
#include "drivers/worker_thread.hpp"
#include "noisemon/command_ack_t.hpp"
#include "noisemon/command_t.hpp"

namespace lcm {
class LCM;
class ReceiveBuffer;
}  // namespace lcm

namespace noisemon::daemon {

class CommandListener {
 public:
  // Opens its own LCM instance on lcm.url and starts listening ("nm-commands"). recorder: null when the daemon does
  // not record ([record] enabled = false): its commands are answered, not ok. Throws naming the URL when it cannot.
  CommandListener(const LcmConfig& lcm, std::shared_ptr<Recorder> recorder);
  ~CommandListener();
  CommandListener(const CommandListener&) = delete;
  CommandListener& operator=(const CommandListener&) = delete;

  // Whether a daemon on `url` listens for commands: on UDP multicast (the bus other processes share), not on a file
  // or in-process provider.
  [[nodiscard]] static bool listens_on(const std::string& url);

 private:
  void on_command(const lcm::ReceiveBuffer* buffer, const std::string& channel, const noisemon::command_t* command);
  void answer(const noisemon::command_t& c, bool ok, const std::string& message);
  void publish(const noisemon::command_ack_t& ack);

  const std::string command_channel_, ack_channel_;
  std::unique_ptr<lcm::LCM> bus_;
  std::shared_ptr<Recorder> recorder_;
  std::mutex mutex_;  // guards seen_ and the bus's publishing (the recorder answers from its writer thread)
  std::deque<std::pair<std::string, std::optional<noisemon::command_ack_t>>> seen_;  // the latest ids, answered or not
  drivers::WorkerThread thread_{"commands"};                                         // last: stopped first
};

}  // namespace noisemon::daemon
