// `noisemon tdc`: thermodynamic TDC from motored cycles (model/motored_tdc.hpp), a motored run directory's (the
// encoder's scale: the result is [combustion] tdc_deg, written into a configuration with --write-config) or a motored
// cycle table's (its own scale: what `import --motored-table` applies).
#pragma once

#include <string>
#include <vector>

#include "model/motored_tdc.hpp"

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

// The cycles [720 k - 360, 720 k + 360) of a run's unwrapped crank angles, each complete one on a grid of step_deg
// from -360 (linear interpolation between encoder samples), bar.
std::vector<std::vector<double>> motored_cycles_bar(const std::vector<double>& crank_deg,
                                                    const std::vector<double>& pressure_pa, double step_deg);

// A motored run's thermodynamic TDC on its encoder's scale (what [combustion] tdc_deg holds): a run directory, or a
// raw log the daemon recorded while motoring (its first run). Throws naming it for a fired run (run.json, the log's
// operating point) or cycles that are not motored (model::motored_tdc).
model::MotoredTdc motored_run_tdc(const std::string& path, double loss_angle_deg);

// Sets tdc_deg in the [combustion] table of the TOML file at path (the line replaced when it is there, added under
// the table otherwise, the table added at the end when there is none); the rest of the file as it was.
void write_tdc_deg(const std::string& path, double tdc_deg);

class TdcCommand {
 public:
  explicit TdcCommand(CLI::App& app);
  // After app.parse(): runs `tdc` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* tdc_ = nullptr;
  std::string run_dir_, table_, write_config_;
  double loss_angle_deg_ = model::kDefaultLossAngleDeg, table_tdc_deg_ = 0.0;
};

}  // namespace noisemon::cli
