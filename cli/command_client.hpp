// Sends one command to noisemond over the bus (command_t on [lcm] command_channel) and waits for its answer
// (command_ack_t): `noisemon record` and the dashboard's recording buttons. The command is repeated under one id
// until answered, since the bus may drop either (the daemon carries out each id once).
#pragma once

#include <optional>
#include <string>

#include "daemon/config.hpp"
#include "daemon/record_command.hpp"
#include "noisemon/command_ack_t.hpp"

namespace noisemon::cli {

struct CommandRequest {
  daemon::CommandVerb verb = daemon::CommandVerb::kMark;
  std::string test_point, text;
};

// `record start NAME`, `record stop`, `record mark TEXT` as a request (action: start, stop or mark); throws
// std::invalid_argument naming what is wrong (a test point that is no name, a mark without its note).
[[nodiscard]] CommandRequest record_request(const std::string& action, const std::string& argument);

// The answer, or nothing when none came within timeout_s. Throws naming the URL when the bus cannot be opened.
[[nodiscard]] std::optional<noisemon::command_ack_t> send_command(const daemon::LcmConfig& lcm,
                                                                  const CommandRequest& request, double timeout_s);

// A command's id unique across the lab's hosts and processes: host, process, a count and the time.
[[nodiscard]] std::string new_command_id();

}  // namespace noisemon::cli
