// noisemond: the engine-noise monitor service. Runs a source (the simulated engine by default), predicts and
// measures dB(A) every engine cycle, and publishes over LCM until SIGINT/SIGTERM (or --cycles N).
#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <csignal>
#include <cstdio>
#include <ctime>
#include <iostream>

#include "daemon/config.hpp"
#include "daemon/pipeline.hpp"
#include "daemon/report_messages.hpp"
#include "daemon/sources.hpp"
#include "drivers/worker_thread.hpp"

namespace {

using namespace noisemon;

int run(int argc, char** argv) {
  CLI::App app{"noisemond - engine-noise monitor: predicted and measured dB(A) per engine cycle over LCM"};
  std::string config_path, source, lcm_url, log_level;
  std::int64_t cycles = -1;
  bool live = false;
  app.add_option("--config", config_path, "TOML configuration file (default: built-in defaults, simulated engine)")
      ->check(CLI::ExistingFile);
  app.add_option("--source", source, "acquisition source, overrides [daemon] source: sim (virtual engine), lcm (raw blocks on the bus), comedi (DAQ card, see [comedi])")
      ->check(CLI::IsMember({"sim", "lcm", "comedi"}));
  app.add_option("--lcm", lcm_url, "LCM URL, overrides [lcm] url (e.g. udpm://239.255.76.67:7667?ttl=0)");
  app.add_option("--cycles", cycles, "stop after publishing N cycles (0 = run until SIGINT/SIGTERM)")->check(CLI::NonNegativeNumber);
  app.add_flag("--live", live, "print one line per cycle on stdout (predicted and measured Lp(A), LW(A))");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical or off")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  auto logger = spdlog::stderr_color_mt("noisemond");
  spdlog::set_default_logger(logger);

  daemon::Config config = config_path.empty() ? daemon::Config{} : daemon::load_config(config_path);
  if (!source.empty()) config.source = source;
  if (!lcm_url.empty()) config.lcm.url = lcm_url;
  if (cycles >= 0) config.cycles = cycles;
  if (live) config.live = true;
  if (!log_level.empty()) config.log_level = log_level;
  if (config.source == "lcm") {
    // The streams come from the bus: publishing them again would feed them back to ourselves.
    config.lcm.publish_raw = false;
    config.lcm.publish_operating_point = false;
  }
  spdlog::set_level(spdlog::level::from_str(config.log_level));

  // Signals are taken synchronously by this thread; every thread started below inherits the mask.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  daemon::Pipeline::ReportHook hook;
  if (config.live) {
    std::cout << daemon::cycle_line_header() << std::endl;
    hook = [](const daemon::CycleReport& r) { std::cout << daemon::cycle_line(daemon::to_message(r)) << std::endl; };
  }
  auto acquisition = daemon::make_source(config);
  if (config.threads.lock_memory) {
    // After the devices are open, so that a missing device is the error reported first; MCL_CURRENT locks what
    // is mapped now, MCL_FUTURE the rings and threads that follow.
    drivers::lock_memory();
    spdlog::info("memory locked (mlockall MCL_CURRENT | MCL_FUTURE)");
  }
  daemon::Pipeline pipeline(config, std::move(acquisition), hook);
  pipeline.start();

  bool notified = false;
  while (!pipeline.finished()) {
    if (!notified && pipeline.ready()) {
      sd_notify(0, "READY=1\nSTATUS=acquiring");
      spdlog::info("ready: all driver threads deliver data");
      notified = true;
    }
    const timespec timeout{0, 100'000'000};
    const int sig = sigtimedwait(&stop_signals, nullptr, &timeout);
    if (sig > 0) {
      spdlog::info("{} received: finishing the last complete cycle", sig == SIGINT ? "SIGINT" : "SIGTERM");
      break;
    }
  }
  sd_notify(0, "STOPPING=1");
  pipeline.stop();
  if (const std::string why = pipeline.failure(); !why.empty()) {
    spdlog::error("{}", why);
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "noisemond: %s\n", e.what());
    return 1;
  }
}
