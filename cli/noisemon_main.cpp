// noisemon: the command-line tool beside the daemon (watch, replay, import, export, sim, fit, diagnose, summary, dash,
// tdc, gapwatch, dbc, calibrate, check, record).
#include <CLI/CLI.hpp>

#include <cstdio>
#include <memory>

#include "cli/calibrate_command.hpp"
#include "cli/check_command.hpp"
#include "cli/dash_command.hpp"
#include "cli/dbc_command.hpp"
#include "cli/diagnose_command.hpp"
#include "cli/fit_command.hpp"
#include "cli/gapwatch_command.hpp"
#include "cli/import_export_cli.hpp"
#include "cli/record_command.hpp"
#include "cli/replay_command.hpp"
#include "cli/sim_command.hpp"
#include "cli/summary_command.hpp"
#include "cli/tdc_command.hpp"
#include "cli/watch.hpp"
#include "daemon/config.hpp"

namespace {

// `noisemon watch` and its options.
CLI::App* add_watch(CLI::App& app, noisemon::cli::WatchOptions& watch, std::string& cell) {
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
  w->add_flag("--stats", watch.stats,
              "print the daemon's 1 Hz rolling statistics instead (mean, std, COV, min, max, Leq(A))");
  w->add_option("--stats-channel", watch.stats_channel, "channel of the statistics messages")->capture_default_str();
  w->add_option("--cell", cell, "test cell id: append _ID to the channels (docs/sources-and-formats.md)");
  return w;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace noisemon::cli;
  CLI::App app{"noisemon - command-line tools for the noisemon engine-noise monitor"};
  app.require_subcommand(1);

  WatchOptions watch;
  std::string watch_cell;
  CLI::App* w = add_watch(app, watch, watch_cell);

  ReplayCommand replay(app);

  ImportExportCommands import_export(app);
  SimCommand sim(app);
  FitCommand fit(app);
  DiagnoseCommand diagnose(app);
  SummaryCommand summary(app);
  DashCommand dash(app);
  TdcCommand tdc(app);
  GapwatchCommand gapwatch(app);
  DbcCommand dbc(app);
  CalibrateCommand calibrate(app);
  CheckCommand check(app);
  RecordCommand record(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    if (w->parsed()) {
      noisemon::daemon::LcmConfig channels;
      channels.report_channel = watch.channel;
      channels.status_channel = watch.status_channel;
      channels.stats_channel = watch.stats_channel;
      noisemon::daemon::set_cell(channels, watch_cell);  // validates the id
      watch.channel = channels.report_channel;
      watch.status_channel = channels.status_channel;
      watch.stats_channel = channels.stats_channel;
      return run_watch(watch);
    }
    if (const int status = import_export.run(); status >= 0) return status;
    if (const int status = sim.run(); status >= 0) return status;
    if (const int status = fit.run(); status >= 0) return status;
    if (const int status = gapwatch.run(); status >= 0) return status;
    if (const int status = diagnose.run(argc, argv); status >= 0) return status;
    if (const int status = summary.run(); status >= 0) return status;
    if (const int status = dash.run(); status >= 0) return status;
    if (const int status = tdc.run(); status >= 0) return status;
    if (const int status = dbc.run(); status >= 0) return status;
    if (const int status = calibrate.run(); status >= 0) return status;
    if (const int status = check.run(); status >= 0) return status;
    if (const int status = record.run(); status >= 0) return status;
    if (const int status = replay.run(); status >= 0) return status;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemon: %s\n", e.what());
    return 1;
  }
  return 0;
}
