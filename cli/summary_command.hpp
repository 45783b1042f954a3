// `noisemon summary LOG|RUN_DIR... [--json] [--csv]`: statistics over the cycles of whole recordings, per run
// (daemon/cycle_statistics.hpp): energy-mean levels, Leq(A), mean, standard deviation, COV, minimum and maximum of
// every scalar of the cycle reports, and the counts of valid and flagged cycles.
#pragma once

#include <string>
#include <vector>

namespace CLI {
class App;
}  // namespace CLI

namespace noisemon::cli {

class SummaryCommand {
 public:
  explicit SummaryCommand(CLI::App& app);
  // After app.parse(): runs `summary` if it was given and returns its exit status; -1 otherwise.
  int run();

 private:
  CLI::App* summary_ = nullptr;
  std::vector<std::string> inputs_;
  std::string config_path_, model_;
  bool json_ = false, csv_ = false, progress_ = true;
};

}  // namespace noisemon::cli
