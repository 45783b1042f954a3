// `noisemon dash [--lcm URL] [--listen HOST:PORT] [--cell ID] [--config FILE]`: a live dashboard of one test cell
// in the browser, and /metrics for Prometheus. Read-only: it subscribes to the cycle, status and operating-point
// channels and never publishes.
#pragma once

#include <string>

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class DashCommand {
 public:
  explicit DashCommand(CLI::App& app);
  // After app.parse(): runs `dash` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* dash_ = nullptr;
  std::string lcm_url_, listen_ = "127.0.0.1:8080", cell_, config_path_;
  bool cell_given_ = false;
  int history_ = 600;
  double max_rate_ = 10;
};

// "HOST:PORT" (or ":PORT", then 127.0.0.1) into its parts; false when malformed.
bool parse_listen_address(const std::string& text, std::string& host, int& port);

}  // namespace noisemon::cli
