// `noisemon replay LOG... [-j N]`: raw LCM logs through the daemon's processing (daemon/replay.hpp).
//
// One log: --out, --csv and --hdf5 name files, a progress bar on a terminal, one summary line at the end (as
// always). Several logs: up to N at a time (-j, default 1), each in a thread of its own with its own pipeline and
// outputs; --out, --csv and --hdf5 then name existing directories, and each log's reports go to
// DIR/<name>.lcmlog, DIR/<name>.csv, DIR/<name>.h5, <name> the log's file name less a ".lcmlog" extension. Two
// logs of the same name, or an output that would replace an input log, are refused before anything runs. One
// line on stderr per finished log; a log that fails does not stop the others (exit status 1 at the end).
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "daemon/replay.hpp"

namespace CLI {
class App;
}

namespace noisemon::cli {

struct MultiReplayOptions {
  std::vector<std::string> logs;
  std::string out_dir, csv_dir, hdf5_dir;  // empty: no such output
  int jobs = 1;                            // logs replayed at the same time
  daemon::ReplayOptions base;              // config, realtime (log_path, outputs and progress are set per log)
};

struct LogReplayResult {
  std::string log;
  daemon::ReplaySummary summary;
  std::string error;     // empty: replayed
  double seconds = 0.0;  // wall time of this log
};

// The name a log's outputs take in the output directories (file name less a ".lcmlog" extension).
std::string replay_output_name(const std::string& log);

// Throws std::invalid_argument naming the option, directory or logs when the outputs are ambiguous: an output
// that is not an existing directory, two logs of the same name, an output that is an input log.
void check_multi_replay(const MultiReplayOptions& options);

// Replays every log (after check_multi_replay), up to options.jobs at a time; calls on_done (serialised, from
// the worker threads) as each log finishes. Results in the order of options.logs; a failure is in its result.
std::vector<LogReplayResult> run_replays(
    const MultiReplayOptions& options,
    const std::function<void(const LogReplayResult&, std::size_t done, std::size_t total)>& on_done = {});

// The `replay` subcommand.
class ReplayCommand {
 public:
  explicit ReplayCommand(CLI::App& app);
  // After app.parse(): runs `replay` if it was given and returns its exit status; -1 otherwise. A single log's
  // failure is thrown (as before); with several logs, failures are printed per log and give status 1.
  int run();

 private:
  int run_one();
  int run_several();
  void apply_config();

  CLI::App* replay_ = nullptr;
  std::vector<std::string> logs_;
  std::string out_, csv_, hdf5_, config_path_, model_;
  int jobs_ = 1;
  daemon::ReplayOptions options_;
};

}  // namespace noisemon::cli
