#include "cli/dash_command.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "cli/command_client.hpp"
#include "cli/dash_reference.hpp"
#include "cli/dash_server.hpp"
#include "cli/dash_state.hpp"
#include "cli/lcm_loop.hpp"
#include "daemon/config.hpp"

namespace noisemon::cli {

bool parse_listen_address(const std::string& text, std::string& host, int& port) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos) return false;
  host = colon == 0 ? "127.0.0.1" : text.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  try {
    std::size_t used = 0;
    port = std::stoi(text.substr(colon + 1), &used);
    return used == text.size() - colon - 1 && port >= 0 && port <= 65535;
  } catch (const std::exception&) {
    return false;
  }
}

DashCommand::DashCommand(CLI::App& app) {
  dash_ = app.add_subcommand(
      "dash",
      "serve a live dashboard of the cycle reports and the daemon's health to browsers, and /metrics for Prometheus");
  dash_->add_option("--lcm", lcm_url_, "LCM URL (default: the configuration's, else LCM's default udpm URL)");
  dash_->add_option("--listen", listen_, "HOST:PORT to serve on (0.0.0.0:PORT: every interface)")
      ->capture_default_str();
  dash_->add_option("--cell", cell_,
                    "test cell id: subscribe to the channels suffixed _ID (default: the configuration's [lcm] cell)");
  dash_->add_option("--config", config_path_, "noisemond TOML configuration, for the channel names and the cell")
      ->check(CLI::ExistingFile);
  dash_->add_option("--history", history_, "cycles kept for the trend")
      ->capture_default_str()
      ->check(CLI::Range(10, 100000));
  dash_->add_option("--max-rate", max_rate_, "events per second to each browser at most")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0));
  dash_->footer("Pages: / (the dashboard), /events (server-sent events), /api/state (JSON), /metrics (Prometheus).");
}

namespace {

constexpr double kRecordAnswerTimeoutS = 5.0;  // the button's wait for the daemon (the command repeats meanwhile)

// The page's recording buttons: the command to the daemon, and its answer as JSON.
ControlAnswer record_control(const daemon::LcmConfig& bus, const std::string& action, const std::string& argument) {
  CommandRequest request;
  try {
    request = record_request(action, argument);
  } catch (const std::invalid_argument& e) {
    return {400, nlohmann::json{{"error", e.what()}}.dump()};
  }
  const auto ack = send_command(bus, request, kRecordAnswerTimeoutS);
  if (!ack)
    return {504, nlohmann::json{{"answered", false},
                                {"message", "no noisemond answered on " + bus.command_channel + " within " +
                                                std::to_string(static_cast<int>(kRecordAnswerTimeoutS)) + " s"}}
                     .dump()};
  return {200,
          nlohmann::json{{"answered", true}, {"ok", ack->ok}, {"message", ack->message}, {"file", ack->file}}.dump()};
}

}  // namespace

int DashCommand::run() {
  if (!dash_->parsed()) return -1;
  daemon::Config config = config_path_.empty() ? daemon::Config{} : daemon::load_config(config_path_);
  if (dash_->count("--cell") > 0) daemon::set_cell(config.lcm, cell_);
  if (dash_->count("--lcm") > 0) config.lcm.url = lcm_url_;
  std::string host;
  int port = 0;
  if (!parse_listen_address(listen_, host, port)) {
    std::fprintf(stderr, "noisemon dash: --listen %s: expected HOST:PORT\n", listen_.c_str());
    return 2;
  }
  lcm::LCM lcm(config.lcm.url);
  if (!lcm.good()) {
    std::fprintf(stderr, "noisemon dash: %s\n", lcm_open_error(config.lcm.url).c_str());
    return 1;
  }
  DashState state(config.lcm.cell, static_cast<std::size_t>(history_), linear_reference_json());
  LcmHandler<noisemon::cycle_report_t> cycles{[&](const auto& m) { state.on_cycle(m); }};
  LcmHandler<noisemon::status_t> status{[&](const auto& m) { state.on_status(m); }};
  LcmHandler<noisemon::operating_point_t> ops{[&](const auto& m) { state.on_operating_point(m); }};
  lcm.subscribe(config.lcm.report_channel, &LcmHandler<noisemon::cycle_report_t>::on, &cycles);
  lcm.subscribe(config.lcm.status_channel, &LcmHandler<noisemon::status_t>::on, &status);
  lcm.subscribe(config.lcm.operating_point_channel, &LcmHandler<noisemon::operating_point_t>::on, &ops);
  LcmHandler<noisemon::gap_event_t> gap_events{[&](const auto& m) { state.on_gap_event(m); }};
  LcmHandler<noisemon::gap_status_t> gap_status{[&](const auto& m) { state.on_gap_status(m); }};
  lcm.subscribe(config.lcm.gap_event_channel, &LcmHandler<noisemon::gap_event_t>::on, &gap_events);
  lcm.subscribe(config.lcm.gap_status_channel, &LcmHandler<noisemon::gap_status_t>::on, &gap_status);
  LcmHandler<noisemon::check_t> check{[&](const auto& m) { state.on_check(m); }};
  lcm.subscribe(config.lcm.check_channel, &LcmHandler<noisemon::check_t>::on, &check);

  DashServer server(state, std::chrono::milliseconds(static_cast<int>(1000.0 / max_rate_)),
                    [bus = config.lcm](const std::string& action, const std::string& argument) {
                      return record_control(bus, action, argument);
                    });
  if (!server.start(host, port)) return 1;
  std::fprintf(stderr, "noisemon dash: http://%s:%d/ (channels %s, %s, %s)\n", host.c_str(), server.port(),
               config.lcm.report_channel.c_str(), config.lcm.status_channel.c_str(),
               config.lcm.operating_point_channel.c_str());
  handle_until_signal(lcm);
  state.stop();
  server.stop();
  std::fprintf(stderr, "noisemon dash: stopped\n");
  return 0;
}

}  // namespace noisemon::cli
