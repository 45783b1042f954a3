// noisemon: the command-line tool beside the daemon (watch; replay, import, fit and diagnose come later).
#include <CLI/CLI.hpp>

#include <cstdio>

#include "daemon/watch.hpp"

int main(int argc, char** argv) {
  using namespace noisemon::daemon;
  CLI::App app{"noisemon - command-line tools for the noisemon engine-noise monitor"};
  app.require_subcommand(1);

  WatchOptions watch;
  CLI::App* w = app.add_subcommand("watch", "subscribe to noisemond's cycle reports and print one line per cycle");
  w->add_option("--lcm", watch.lcm_url, "LCM URL (default: LCM's default udpm URL)");
  w->add_option("--channel", watch.channel, "channel of the cycle reports")->capture_default_str();
  w->add_option("--count", watch.count, "exit after N reports (0 = until Ctrl-C)")->check(CLI::NonNegativeNumber);
  w->add_option("--timeout", watch.timeout_s, "fail when no report arrives for this many seconds (0 = wait forever)")
      ->check(CLI::NonNegativeNumber);
  w->add_option("--csv", watch.csv_path, "also write one CSV row per report to this file");
  w->add_flag("--bands", watch.bands, "also print each report's 1/3-octave spectra");
  w->add_flag("--status", watch.status, "print the daemon's 1 Hz status messages instead (threads, rings, counters)");
  w->add_option("--status-channel", watch.status_channel, "channel of the status messages")->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (w->parsed()) return run_watch(watch);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemon: %s\n", e.what());
    return 1;
  }
  return 0;
}
