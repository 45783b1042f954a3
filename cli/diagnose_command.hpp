// `noisemon diagnose`: the sim-to-real gap. Where the tuned block model and the measurements disagree, which
// unmodelled effect of the list (docs/diagnosis.md) explains it, and how much of the held-out gap that effect closes.
//   band mode      DATA = run directories or raw LCM logs (cli/band_data): model/diagnosis on 1/3-octave
//                  spectra; --train / --holdout take condition patterns (model::diagnosis::condition_matches); without
//                  --holdout every fired condition is held out in turn (leave-one-condition-out).
//   waveform mode  DATA = CSV files of `u,y` at --fs (as `noisemon fit`): model/diagnosis/waveform_diagnosis on the
//   free-run
//                  error; --train / --holdout take sample ranges or DATA names; --test NAME=A:B scores the
//                  baseline and the best model on further ranges (e.g. a benchmark's test sets).
// Writes DIR/report.json (cli/report/diagnosis_report) and DIR/report.html (cli/report/report_html), prints a summary.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace CLI {
class App;
}

namespace noisemon::cli {

struct DiagnoseOptions {
  std::vector<std::string> data;
  std::string out_dir;
  std::string mode;   // "band", "waveform" or "" (from DATA)
  std::string model;  // preset or parameter file the baseline is tuned from ("": band mode
                      // linear; waveform mode the nearest preset or the data's estimate)
  std::vector<std::string> train, holdout;
  std::string candidates;          // comma-separated subset of the effects ("" = all)
  std::string free;                // baseline free parameters ("" = the mode's default)
  double fs_hz = 0.0;              // waveform mode
  std::size_t settle = 50;         // waveform mode: samples per segment that only settle the state
  int max_iterations = 40;         // waveform mode: Ceres iterations per fit
  std::vector<std::string> tests;  // waveform mode: NAME=A:B
  std::size_t fit_cycles = 8;      // band mode: re-simulated cycles per condition in the fits
  int bootstrap = 200;
  std::uint64_t seed = 1;
  double tolerance_db = 0.5;   // band mode: a held-out gap below this is `none`
  std::string pressure_floor;  // band mode: "" (the runs' own), "estimate", or bar rms per encoder sample
  bool force = false;          // replace an existing report in DIR
  bool progress = true;
  std::string command_line;  // for the report's record
};

struct DiagnoseOutcome {
  nlohmann::json report;
  std::string json_path, html_path;
};

// Runs the diagnosis, prints the summary to `out` (nullptr: nowhere), writes DIR/report.json and DIR/report.html.
// Throws std::exception with a message naming the file, option or condition at fault; nothing is written then.
DiagnoseOutcome run_diagnose(const DiagnoseOptions& options, std::FILE* out = stdout);

class DiagnoseCommand {
 public:
  explicit DiagnoseCommand(CLI::App& app);
  // After app.parse(): runs `diagnose` if it was given and returns its exit status; -1 otherwise.
  int run(int argc, char** argv);

 private:
  CLI::App* cmd_ = nullptr;
  DiagnoseOptions options_;
};

}  // namespace noisemon::cli
