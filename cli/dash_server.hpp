// `noisemon dash`: the HTTP server (cpp-httplib): the page and its assets, built into the binary; /events, the
// server-sent events, throttled per client; /api/state, the JSON snapshot; /metrics, Prometheus text; POST
// /api/record, the recording's buttons (the daemon's recorder started, stopped or marked by command).
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "cli/dash_state.hpp"

namespace httplib {
class Server;
}

namespace noisemon::cli {

// What POST /api/record answers to {"action": "start" | "stop" | "mark", "argument": "..."}: an HTTP status and JSON.
struct ControlAnswer {
  int status = 200;
  std::string json;
};
using RecordControl = std::function<ControlAnswer(const std::string& action, const std::string& argument)>;

class DashServer {
 public:
  // At most one event per `min_interval` for each client. record_control: empty, and POST /api/record is 404.
  DashServer(DashState& state, std::chrono::milliseconds min_interval, RecordControl record_control = {});
  ~DashServer();
  // Binds host:port and serves on a thread of its own; false (and a message on stderr) when it cannot bind.
  bool start(const std::string& host, int port);
  // Ends every event stream and the server; call after state.stop().
  void stop();
  int port() const { return port_; }

 private:
  void routes();
  DashState& state_;
  const std::chrono::milliseconds min_interval_;
  RecordControl record_control_;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  int port_ = 0;
};

}  // namespace noisemon::cli
