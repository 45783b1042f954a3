// `noisemon gapwatch`: the live gap watch (model/diagnosis/gap_watch.hpp) beside the daemon, on its cycle reports over
// LCM, or on a log (the same events: the watch reads the same reports in the same order). Events go to
// NOISEMON_GAP_EVENT (gap_event_t), one line each on stdout, and with --json one JSON object per line.
#pragma once

#include <string>

#include "model/diagnosis/gap_watch.hpp"

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class GapwatchCommand {
 public:
  explicit GapwatchCommand(CLI::App& app);
  // After app.parse(): runs `gapwatch` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* gapwatch_ = nullptr;
  std::string lcm_url_, log_, json_, reference_, save_reference_, config_path_, cell_, model_;
  bool publish_ = false, progress_ = true;
  double encoder_step_deg_ = 0.1;
  model::diagnosis::GapWatchOptions options_;
};

}  // namespace noisemon::cli
