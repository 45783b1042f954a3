// `noisemon fit`: tunes the block model (eq. 4.13; m fixed) and writes a parameter file the daemon loads
// (daemon/params_file.hpp).
//   band mode      DATA = run directories or raw LCM logs (cli/band_data); the thesis metric: RMS over the
//                  scored 1/3-octave bands of the cycle-averaged attenuation-curve gap, averaged over
//                  conditions (model/fit/band_fit). --holdout takes condition patterns
//                  (model::diagnosis::condition_matches).
//   waveform mode  DATA = CSV files of `u,y` sampled at --fs (drivers/formats/waveform_csv); free-run simulation error
//                  (model/fit/waveform_fit). --train / --holdout take sample ranges `A:B` (0-based, half-open, over
//                  the DATA files concatenated) or DATA file names; without them the last DATA file is held out,
//                  or the last 20 % of a single file.
// The mode is chosen from DATA (`.csv` files: waveform) unless --mode says otherwise.
#pragma once

#include <cstddef>
#include <cstdio>
#include <string>
#include <vector>

#include "model/block_params.hpp"
#include "model/fit/band_fit.hpp"
#include "model/fit/waveform_fit.hpp"

namespace CLI {
class App;
}

namespace noisemon::cli {

struct FitCommandOptions {
  std::vector<std::string> data;
  std::string out;                   // parameter file to write ("" = write nothing)
  std::string mode;                  // "band", "waveform" or "" (from DATA)
  double fs_hz = 0.0;                // waveform mode: sample rate of the CSV
  std::string free;                  // comma-separated parameter names ("" = the mode's default set)
  std::string model;                 // preset or parameter file to start from ("" = the nearest preset)
  std::vector<std::string> holdout;  // band: condition patterns; waveform: ranges A:B or DATA names
  std::vector<std::string> train;    // the same; empty = everything not held out
  std::size_t settle = 50;           // waveform: samples per segment that only settle the initial state
  std::size_t fit_cycles = 8;        // band: re-simulated cycles per condition during the fit
  int max_iterations = 60;           // waveform: Ceres iterations
  bool progress = true;              // on stderr, when it is a terminal
  bool force = false;                // overwrite an existing output file
};

struct FitCommandResult {
  std::string mode;
  std::string start_name;             // the preset / file / estimate the fit started from
  model::BlockParams params;          // what was written
  std::vector<std::string> free;      // fitted parameters
  std::vector<double> values, sigma;  // per free parameter: value and 1-sigma (Jacobian, white residuals)
  std::vector<double> sigma_blocks;   // waveform mode: the same allowing for correlated residuals (else empty)
  std::string units;                  // of the RMS figures: "dB" (band) or "data units" (waveform)
  double start_train_rms = 0.0;
  double train_rms = 0.0;
  double heldout_rms = 0.0;                           // NaN when nothing is held out
  std::vector<std::string> train_sets, heldout_sets;  // condition names or ranges
  double seconds = 0.0;
};

// Waveform DATA and the split `fit` uses (shared with `noisemon diagnose` in waveform mode): the CSV files
// concatenated, and the training / held-out ranges from --train / --holdout (see the top of the file). Throws
// naming the file, line or option. `note` receives one line per file read.
struct WaveformData {
  std::vector<double> u, y;
  std::vector<std::string> files;
  std::vector<model::fit::SampleRange> file_ranges;  // where each file lies in u, y
  std::vector<model::fit::SampleRange> train, heldout;
};
WaveformData load_waveform_data(const std::vector<std::string>& paths, const std::vector<std::string>& train,
                                const std::vector<std::string>& holdout, std::size_t settle_samples,
                                std::FILE* note = nullptr);

// Band mode's --free: "k1,b1,c0" -> parameters ("" -> none: the mode's default); throws naming --free.
std::vector<model::fit::BlockParam> parse_free_option(const std::string& text);

// "A:B" (0-based, end excluded) or a DATA file name -> a range of `data`; throws naming `option` and the text.
model::fit::SampleRange parse_range(const std::string& text, const WaveformData& data, const char* option);

// Runs the fit, prints the summary to `out`, writes options.out. Throws std::exception with a message that
// names the file, option, parameter or condition at fault; nothing is written when the fit fails.
FitCommandResult run_fit(const FitCommandOptions& options, std::FILE* out = stdout);

// The `fit` subcommand.
class FitCommand {
 public:
  explicit FitCommand(CLI::App& app);
  // After app.parse(): runs `fit` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* fit_ = nullptr;
  FitCommandOptions options_;
};

}  // namespace noisemon::cli
