// `noisemon record start NAME | stop | mark TEXT`: the test bed's (or the engineer's) commands to a running
// noisemond's recorder, over the configuration's bus ([lcm] url and cell), each answered by the daemon: a recording
// of test point NAME from now (the one running ends), the end of it, or a mark where it is now.
// Exit status 0 when carried out, 1 when refused (the answer says why), 2 when no daemon answered in time.
#pragma once

#include <string>

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class RecordCommand {
 public:
  explicit RecordCommand(CLI::App& app);
  // After app.parse(): runs `record` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* record_ = nullptr;
  std::string action_, argument_, config_path_, lcm_url_, cell_;
  double timeout_s_ = 5.0;
};

}  // namespace noisemon::cli
