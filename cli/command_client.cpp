#include "cli/command_client.hpp"

#include <unistd.h>
#include <lcm/lcm-cpp.hpp>

#include <atomic>
#include <chrono>
#include <stdexcept>

#include "cli/lcm_loop.hpp"
#include "daemon/record_files.hpp"
#include "drivers/source.hpp"
#include "noisemon/command_t.hpp"

namespace noisemon::cli {
namespace {

constexpr auto kRepeatEvery = std::chrono::milliseconds(500);

struct AckWaiter {
  std::string id;
  std::optional<noisemon::command_ack_t> ack;
  void on_ack(const ::lcm::ReceiveBuffer*, const std::string&, const noisemon::command_ack_t* a) {
    if (a->id == id) ack = *a;
  }
};

}  // namespace

CommandRequest record_request(const std::string& action, const std::string& argument) {
  CommandRequest r;
  if (action == "start") {
    if (!daemon::valid_test_point(argument))
      throw std::invalid_argument("record start: test point '" + argument + "': " + daemon::kTestPointRule);
    r.verb = daemon::CommandVerb::kRecordStart;
    r.test_point = argument;
  } else if (action == "stop") {
    if (!argument.empty()) throw std::invalid_argument("record stop: takes no argument (got '" + argument + "')");
    r.verb = daemon::CommandVerb::kRecordStop;
  } else if (action == "mark") {
    if (argument.empty())
      throw std::invalid_argument("record mark: say what happened, e.g. record mark \"door opened\"");
    r.verb = daemon::CommandVerb::kMark;
    r.text = argument;
  } else {
    throw std::invalid_argument("record: '" + action + "': expected start, stop or mark");
  }
  return r;
}

std::string new_command_id() {
  static std::atomic<int> count{0};
  char host[64] = "host";
  (void)gethostname(host, sizeof host - 1);
  return std::string(host) + "-" + std::to_string(getpid()) + "-" + std::to_string(++count) + "-" +
         std::to_string(drivers::wall_utime());
}

std::optional<noisemon::command_ack_t> send_command(const daemon::LcmConfig& lcm, const CommandRequest& request,
                                                    double timeout_s) {
  ::lcm::LCM bus(lcm.url);
  if (!bus.good()) throw std::runtime_error(lcm_open_error(lcm.url));
  noisemon::command_t command;
  command.id = new_command_id();
  command.verb = std::string(daemon::command_verb_name(request.verb));
  command.test_point = request.test_point;
  command.text = request.text;
  AckWaiter waiter{command.id, std::nullopt};
  bus.subscribe(lcm.command_ack_channel, &AckWaiter::on_ack, &waiter);
  using Clock = std::chrono::steady_clock;
  const auto deadline =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  auto next_send = Clock::now();
  while (!waiter.ack && Clock::now() < deadline) {
    if (Clock::now() >= next_send) {
      command.utime = drivers::wall_utime();
      bus.publish(lcm.command_channel, &command);
      next_send += kRepeatEvery;
    }
    bus.handleTimeout(50);
  }
  return waiter.ack;
}

}  // namespace noisemon::cli
