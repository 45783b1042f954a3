#include "daemon/command_listener.hpp"

#include <spdlog/spdlog.h>
#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "daemon/record_command.hpp"
#include "drivers/source.hpp"

namespace noisemon::daemon {
namespace {

constexpr std::size_t kRememberedIds = 256;  // far more than a test bed sends while one of them is repeated
constexpr int kHandleTimeoutMs = 100;        // how soon the thread sees a stop

}  // namespace

bool CommandListener::listens_on(const std::string& url) { return url.empty() || url.rfind("udpm://", 0) == 0; }

CommandListener::CommandListener(const LcmConfig& lcm, std::shared_ptr<Recorder> recorder)
    : command_channel_(lcm.command_channel),
      ack_channel_(lcm.command_ack_channel),
      bus_(std::make_unique<::lcm::LCM>(lcm.url)),
      recorder_(std::move(recorder)) {
  if (!bus_->good())
    throw std::runtime_error("commands: cannot open LCM at '" +
                             (lcm.url.empty() ? std::string("default URL") : lcm.url) + "'");
  if (recorder_) recorder_->set_ack_sink([this](const noisemon::command_ack_t& ack) { publish(ack); });
  bus_->subscribe(command_channel_, &CommandListener::on_command, this);
  thread_.start("nm-commands", {}, [this](const std::atomic<bool>& stop) {
    while (!stop.load(std::memory_order_relaxed)) bus_->handleTimeout(kHandleTimeoutMs);
  });
  spdlog::info("listening for commands on {} (answers on {})", command_channel_, ack_channel_);
}

CommandListener::~CommandListener() {
  thread_.stop();
  if (recorder_) recorder_->set_ack_sink({});
}

void CommandListener::on_command(const ::lcm::ReceiveBuffer*, const std::string&, const noisemon::command_t* c) {
  if (c->id.empty()) return answer(*c, false, "a command needs an id (its repeats carry the same)");
  {
    std::lock_guard lock(mutex_);
    const auto seen = std::find_if(seen_.begin(), seen_.end(), [&](const auto& s) { return s.first == c->id; });
    if (seen != seen_.end()) {
      if (seen->second) bus_->publish(ack_channel_, &*seen->second);  // a repeat: its answer was lost
      return;
    }
    seen_.emplace_back(c->id, std::nullopt);
    if (seen_.size() > kRememberedIds) seen_.pop_front();
  }
  const std::optional<CommandVerb> verb = command_verb(c->verb);
  if (!verb) return answer(*c, false, "unknown verb '" + c->verb + "': record_start, record_stop or mark");
  if (!recorder_) return answer(*c, false, "this daemon does not record ([record] enabled = false)");
  spdlog::info("command {} {} {}", c->verb, c->test_point, c->text);
  recorder_->request({*verb, c->id, c->test_point, c->text});
}

// An answer of the listener's own (the command never reached the recorder).
void CommandListener::answer(const noisemon::command_t& c, bool ok, const std::string& message) {
  noisemon::command_ack_t ack;
  ack.utime = drivers::wall_utime();
  ack.id = c.id;
  ack.verb = c.verb;
  ack.test_point = c.test_point;
  ack.text = c.text;
  ack.ok = ok;
  ack.message = message;
  publish(ack);
}

void CommandListener::publish(const noisemon::command_ack_t& ack) {
  std::lock_guard lock(mutex_);
  const auto seen = std::find_if(seen_.begin(), seen_.end(), [&](const auto& s) { return s.first == ack.id; });
  if (seen != seen_.end()) seen->second = ack;
  bus_->publish(ack_channel_, &ack);
}

}  // namespace noisemon::daemon
