// `noisemon watch`: subscribe to the cycle reports and print one line per cycle.
#pragma once

#include <cstdint>
#include <string>

namespace noisemon::cli {

struct WatchOptions {
  std::string lcm_url;
  std::string channel = "NOISEMON_CYCLE";
  std::int64_t count = 0;  // exit after this many reports (0 = until SIGINT/SIGTERM)
  double timeout_s = 0;    // exit with an error when no report arrives for this long (0 = wait forever)
  std::string csv_path;    // also write one CSV row per report
  bool bands = false;      // also print the band spectra of each report
  bool status = false;     // print the 1 Hz status messages instead of cycle reports
  std::string status_channel = "NOISEMON_STATUS";
  bool stats = false;  // print the 1 Hz rolling statistics instead (cycle_stats_t)
  std::string stats_channel = "NOISEMON_STATS";
};

// Returns the process exit code.
int run_watch(const WatchOptions& options);

}  // namespace noisemon::cli
