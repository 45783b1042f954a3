#include "cli/record_command.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <stdexcept>

#include "cli/command_client.hpp"
#include "daemon/config.hpp"

namespace noisemon::cli {
namespace {

constexpr int kNoAnswer = 2;

}  // namespace

RecordCommand::RecordCommand(CLI::App& app) {
  record_ = app.add_subcommand(
      "record",
      "start or stop a running noisemond's recording of a test point, or mark an event in it: record start NAME, "
      "record stop, record mark TEXT (exit status 0 done, 1 refused, 2 no daemon answered)");
  record_->add_option("action", action_, "start, stop or mark")
      ->required()
      ->check(CLI::IsMember({"start", "stop", "mark"}));
  record_->add_option("argument", argument_, "start: the test point's name (letters, digits, . _ -); mark: the note");
  record_->add_option("--config", config_path_, "the daemon's configuration file: its [lcm] url and cell")
      ->check(CLI::ExistingFile);
  record_->add_option("--lcm", lcm_url_, "LCM URL, overrides [lcm] url");
  record_->add_option("--cell", cell_, "test cell id, overrides [lcm] cell");
  record_->add_option("--timeout", timeout_s_, "how long to wait for the daemon's answer, s")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 600.0));
}

int RecordCommand::run() {
  if (!record_->parsed()) return -1;
  const CommandRequest request = record_request(action_, argument_);
  daemon::Config config = config_path_.empty() ? daemon::Config{} : daemon::load_config(config_path_);
  if (!lcm_url_.empty()) config.lcm.url = lcm_url_;
  if (!cell_.empty()) daemon::set_cell(config.lcm, cell_);
  const auto ack = send_command(config.lcm, request, timeout_s_);
  if (!ack) {
    std::fprintf(stderr,
                 "record %s: no noisemond answered on %s within %.0f s: is it running, on this bus (%s) and cell "
                 "(%s)?\n",
                 action_.c_str(), config.lcm.command_channel.c_str(), timeout_s_,
                 config.lcm.url.empty() ? "LCM's default URL" : config.lcm.url.c_str(),
                 config.lcm.cell.empty() ? "none" : config.lcm.cell.c_str());
    return kNoAnswer;
  }
  std::printf("%s: %s\n", ack->ok ? "done" : "refused", ack->message.c_str());
  if (!ack->file.empty()) std::printf("file: %s\n", ack->file.c_str());
  return ack->ok ? 0 : 1;
}

}  // namespace noisemon::cli
