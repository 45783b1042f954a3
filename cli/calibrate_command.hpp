// `noisemon calibrate`: a sound calibrator on one microphone; the tone's frequency and steadiness checked, the
// microphone's sensitivity derived from the level the calibrator states and written into the configuration file
// (that value alone: comments and every other line kept, the file replaced atomically), and the calibration
// appended to the cell's history. A sensitivity that moved more than 0.5 dB since the microphone's last
// calibration is a warning: a damaged capsule, a loose connector, a preamplifier's gain turned. With --pressure, the
// in-cylinder pressure chain's zero or gain instead (pressure_calibration.hpp).
#pragma once

#include <string>

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class CalibrateCommand {
 public:
  explicit CalibrateCommand(CLI::App& app);
  // After app.parse(): runs `calibrate` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  int run_microphone();

  CLI::App* calibrate_ = nullptr;
  std::string config_path_, history_path_, serial_;
  int mic_ = 0;
  double level_db_ = 94.0, freq_hz_ = 1000.0, seconds_ = 5.0;
  bool pressure_ = false, gain_ = false;
  double reference_bar_ = 0.0;
  bool dry_run_ = false;
};

}  // namespace noisemon::cli
