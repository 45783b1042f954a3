// `noisemon check`: the pre-test check of the measurement chain a test engineer runs before the engine starts (or
// while it is motored): each microphone's level and noise floor and whether it is dead, clipped or implausible
// against the others; the pressure transducer's offset with the engine stopped; the encoder's checks when it turns;
// the CAN bus's operating points; the drivers' error counters. One table; exit status 1 when something is wrong.
// With --publish the table also goes out on LCM (check_t, [lcm] check_channel): `noisemon dash` shows it.
#pragma once

#include <string>

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class CheckCommand {
 public:
  explicit CheckCommand(CLI::App& app);
  // After app.parse(): runs `check` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* check_ = nullptr;
  std::string config_path_;
  double seconds_ = 3.0;
  bool publish_ = false;
};

}  // namespace noisemon::cli
