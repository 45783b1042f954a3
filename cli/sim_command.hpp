// `noisemon sim`: run directories from the virtual engine with effects injected into the "true" engine (one
// per condition, the interchange format of docs/sources-and-formats.md) and DIR/truth.json recording what was injected
// and every setting of the virtual test cell (for the user's own checking; the diagnosis never reads it). The test cell
// is realistic by default (pressure-chain floor and ADC, microphone self-noise, directivity and ADC, gas ringing); each
// run.json records the configured pressure floor (pressure.noise_floor_bar).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace noisemon::cli {

struct SimOptions {
  std::vector<std::string> conditions;     // names or "all" (cli::thesis_conditions)
  std::vector<std::string> effects;        // NAME[=MAGNITUDE][,key=value...] (model/engine/effects.hpp)
  std::vector<std::string> pressure_dirs;  // instead of conditions: run directories whose pressure drives the sim
  int cycles = 40;
  std::uint64_t seed = 1;
  std::string true_model = "linear";  // preset or parameter file (daemon/params_file.hpp)
  double encoder_deg = 0.2;
  double pressure_floor_bar = 0.02;  // the pressure chain's white floor, bar rms per encoder sample;
                                     // 0: an ideal pressure chain (no floor, no ADC)
  bool ideal_cell = false;           // no chain floors, ADCs, directivity or gas ringing at all
  bool background_run = false;       // add the engine-off run "background"
  std::string out_dir;
  bool force = false;    // replace existing run directories
  bool progress = true;  // on stderr, when it is a terminal
};

struct SimSummary {
  std::vector<std::string> run_dirs;  // written, in order
  double generate_s = 0.0;            // CPU time generating (without writing)
  double write_s = 0.0;
  std::uint64_t pressure_clipped = 0;  // samples the ADCs clipped, over every run
  std::uint64_t mic_clipped = 0;
  std::vector<std::string> warnings;  // one per run that clipped
};

// Generates and writes every run and DIR/truth.json. Throws std::exception with a message naming the
// condition, effect, file or directory at fault; nothing is written when the options are wrong.
SimSummary run_sim(const SimOptions& options);

// The `sim` subcommand: options, --help with every effect, --list-effects.
class SimCommand {
 public:
  explicit SimCommand(CLI::App& app);
  // After app.parse(): runs `sim` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* sim_ = nullptr;
  SimOptions options_;
  bool list_effects_ = false;
};

}  // namespace noisemon::cli
